#include "backend.hpp"

#include <stdexcept>
#include <thread>

namespace dynbvh::study {

std::string Backend::default_name() {
    // TBB first: Embree runs on TBB too, so both libraries share one pool of workers instead of two
    // pools of spinning threads competing for the cores; and TBB's work stealing does not wait at
    // barriers for a thread the OS has descheduled (on a busy machine OpenMP builds were 10-30x slower).
#if defined(DYNBVH_WITH_TBB)
    return "tbb";
#elif defined(_OPENMP)
    return "omp";
#else
    return "serial";
#endif
}

std::string Backend::available() {
    std::string s;
#if defined(_OPENMP)
    s += "omp ";
#endif
#if defined(DYNBVH_WITH_TBB)
    s += "tbb ";
#endif
    return s + "serial";
}

Backend Backend::make(const std::string& requested, int threads) {
    const int cores = std::max(1, int(std::thread::hardware_concurrency()));
    const int n = threads > 0 ? threads : cores;
    std::string name = requested;
    if (name.empty()) name = default_name();
    if (name == "serial") return Backend(exec::serial{}, name, 1);
#if defined(_OPENMP)
    if (name == "omp") return Backend(exec::omp{.threads = n}, name, n);
#endif
#if defined(DYNBVH_WITH_TBB)
    if (name == "tbb") return Backend(exec::tbb{n}, name, n);
#endif
    throw std::invalid_argument("--backend " + name + " is not compiled into this binary (available: " + available() + ")");
}

void Backend::for_tasks(std::size_t n, const std::function<void(std::size_t)>& f) const {
    std::visit([&](const auto& ex) { ex.for_tasks(n, f); }, ex_);
}

} // namespace dynbvh::study
