// The executor chosen on the command line (--backend, --threads), held once for the whole run
// so that builders and the tracing loop share it (and TBB's arena is created only once).
#pragma once

#include <cstddef>
#include <functional>
#include <string>
#include <variant>

#include <dynbvh/executor.hpp>

namespace dynbvh::study {

class Backend {
public:
    using Variant = std::variant<exec::serial
#if defined(_OPENMP)
                                 , exec::omp
#endif
#if defined(DYNBVH_WITH_TBB)
                                 , exec::tbb
#endif
                                 >;

    /// `name` omp | tbb | serial (empty: default_name()); `threads` 0 = every core.
    /// Throws std::invalid_argument when the backend is not compiled in.
    static Backend make(const std::string& name, int threads);
    /// The backend used when none is asked for: tbb when compiled in, else omp, else serial.
    static std::string default_name();
    /// Backends compiled into this binary, best first.
    static std::string available();

    const std::string& name() const noexcept { return name_; }
    int threads() const noexcept { return threads_; }
    /// Runs f(0) .. f(n-1), all possibly at once (dynamic scheduling): the tracing loop over tiles.
    void for_tasks(std::size_t n, const std::function<void(std::size_t)>& f) const;
    template <class F>
    decltype(auto) visit(F&& f) const { return std::visit(std::forward<F>(f), ex_); }

private:
    Backend(Variant ex, std::string name, int threads) : ex_(std::move(ex)), name_(std::move(name)), threads_(threads) {}
    Variant ex_;
    std::string name_;
    int threads_ = 1;
};

} // namespace dynbvh::study
