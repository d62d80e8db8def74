// SPDX-License-Identifier: MIT
/// @file executor.hpp
/// Threading backends as one policy type passed to every builder: `exec::serial`,
/// `exec::omp` (OpenMP; compile with -fopenmp, or link dynbvh::omp) and `exec::tbb`
/// (oneTBB; define DYNBVH_WITH_TBB, or link dynbvh::tbb). Algorithms contain no
/// threading code of their own: they call these six primitives.
///
///  - concurrency()                  number of workers
///  - for_each(b, e, f(i))           parallel loop
///  - for_blocks(b, e, f(lo, hi))    parallel loop over contiguous chunks
///  - for_tasks(n, f(k))             n tasks, all may run at once (per-thread histograms)
///  - reduce(b, e, id, map(i), comb) parallel reduction, comb associative
///  - exclusive_scan(in, out)        parallel prefix sum, in == out allowed; returns the total
#pragma once

#include <algorithm>
#include <concepts>
#include <cstddef>
#include <span>
#include <vector>

#if defined(_OPENMP)
#include <omp.h>
#endif

#if defined(DYNBVH_WITH_TBB)
#include <memory>
#include <mutex>
#include <optional>
#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>
#include <tbb/parallel_reduce.h>
#include <tbb/task_arena.h>
#endif

namespace dynbvh::exec {

namespace detail {
/// Serial scan shared by every backend for small inputs and for the block sums.
template <class T>
T serial_exclusive_scan(std::span<const T> in, std::span<T> out) {
    T sum{};
    for (std::size_t i = 0; i < in.size(); ++i) {
        const T v = in[i];
        out[i] = sum;
        sum = sum + v;
    }
    return sum;
}

/// Two-pass blocked exclusive scan on any executor: block sums, scan of the sums, local scans.
template <class Exec, class T>
T blocked_exclusive_scan(const Exec& ex, std::span<const T> in, std::span<T> out) {
    const std::size_t n = in.size();
    const std::size_t workers = ex.concurrency();
    if (workers <= 1 || n < 1u << 14) return serial_exclusive_scan(in, out);
    const std::size_t blocks = workers * 4;
    const std::size_t chunk = (n + blocks - 1) / blocks;
    std::vector<T> sums(blocks + 1);
    ex.for_tasks(blocks, [&](std::size_t b) {
        const std::size_t lo = std::min(n, b * chunk), hi = std::min(n, lo + chunk);
        T s{};
        for (std::size_t i = lo; i < hi; ++i) s = s + in[i];
        sums[b] = s;
    });
    sums[blocks] = serial_exclusive_scan(std::span<const T>(sums.data(), blocks), std::span<T>(sums.data(), blocks));
    ex.for_tasks(blocks, [&](std::size_t b) {
        const std::size_t lo = std::min(n, b * chunk), hi = std::min(n, lo + chunk);
        T s = sums[b];
        for (std::size_t i = lo; i < hi; ++i) {
            const T v = in[i];
            out[i] = s;
            s = s + v;
        }
    });
    return sums[blocks];
}
} // namespace detail

/// Runs everything on the calling thread. Always available.
struct serial {
    /// Number of workers: 1.
    std::size_t concurrency() const noexcept { return 1; }

    /// f(i) for i in [b, e), in order (the grain is ignored).
    template <class F> void for_each(std::size_t b, std::size_t e, F&& f, std::size_t = 0) const {
        for (std::size_t i = b; i < e; ++i) f(i);
    }
    /// f(b, e) once (the grain is ignored).
    template <class F> void for_blocks(std::size_t b, std::size_t e, F&& f, std::size_t = 0) const {
        if (b < e) f(b, e);
    }
    /// f(k) for k in [0, n), in order.
    template <class F> void for_tasks(std::size_t n, F&& f) const {
        for (std::size_t k = 0; k < n; ++k) f(k);
    }
    /// combine(... combine(identity, map(b)) ..., map(e - 1)), left to right.
    template <class T, class Map, class Combine>
    T reduce(std::size_t b, std::size_t e, T identity, Map&& map, Combine&& combine) const {
        T acc = identity;
        for (std::size_t i = b; i < e; ++i) acc = combine(acc, map(i));
        return acc;
    }
    /// out[i] = in[0] + ... + in[i - 1]; returns the total. `in` and `out` may be the same array.
    template <class T> T exclusive_scan(std::span<const T> in, std::span<T> out) const {
        return detail::serial_exclusive_scan(in, out);
    }
};

#if defined(_OPENMP)
/// OpenMP backend. `threads == 0` uses omp_get_max_threads().
struct omp {
    /// Threads to use; 0 (default): omp_get_max_threads() (OMP_NUM_THREADS).
    int threads = 0;

    /// Number of workers, nthreads().
    std::size_t concurrency() const noexcept { return static_cast<std::size_t>(nthreads()); }
    /// `threads`, or omp_get_max_threads() when it is 0.
    int nthreads() const noexcept { return threads > 0 ? threads : omp_get_max_threads(); }

    /// f(i) for i in [b, e) in parallel (static schedule); ranges of at most `grain` indices run on the calling thread.
    template <class F> void for_each(std::size_t b, std::size_t e, F&& f, std::size_t grain = 1024) const {
        if (e <= b) return;
        if (e - b <= grain || nthreads() == 1) {
            for (std::size_t i = b; i < e; ++i) f(i);
            return;
        }
#pragma omp parallel for schedule(static) num_threads(nthreads())
        for (std::size_t i = b; i < e; ++i) f(i);
    }
    /// f(lo, hi) over contiguous chunks of [b, e) of at least about `grain` indices (at most 4 chunks per
    /// thread), dynamically scheduled.
    template <class F> void for_blocks(std::size_t b, std::size_t e, F&& f, std::size_t grain = 1024) const {
        if (e <= b) return;
        const std::size_t n = e - b;
        const std::size_t blocks = std::min<std::size_t>(std::max<std::size_t>(1, n / std::max<std::size_t>(grain, 1)),
                                                         std::size_t(nthreads()) * 4);
        if (blocks <= 1) { f(b, e); return; }
        const std::size_t chunk = (n + blocks - 1) / blocks;
#pragma omp parallel for schedule(dynamic, 1) num_threads(nthreads())
        for (std::size_t k = 0; k < blocks; ++k) {
            const std::size_t lo = b + std::min(n, k * chunk), hi = b + std::min(n, (k + 1) * chunk);
            if (lo < hi) f(lo, hi);
        }
    }
    /// f(k) for k in [0, n), one task each, dynamically scheduled; all may run at once.
    template <class F> void for_tasks(std::size_t n, F&& f) const {
        if (n == 1 || nthreads() == 1) { for (std::size_t k = 0; k < n; ++k) f(k); return; }
#pragma omp parallel for schedule(dynamic, 1) num_threads(nthreads())
        for (std::size_t k = 0; k < n; ++k) f(k);
    }
    /// `combine` over map(i) for i in [b, e), from `identity`; `combine` must be associative (chunks are
    /// reduced in order and combined in index order, so the result does not depend on timing).
    template <class T, class Map, class Combine>
    T reduce(std::size_t b, std::size_t e, T identity, Map&& map, Combine&& combine) const {
        if (e <= b) return identity;
        const std::size_t tasks = std::min<std::size_t>(std::size_t(nthreads()) * 4, (e - b + 1023) / 1024);
        if (tasks <= 1) return serial{}.reduce(b, e, identity, map, combine);
        std::vector<T> partial(tasks, identity);
        const std::size_t chunk = (e - b + tasks - 1) / tasks;
        for_tasks(tasks, [&](std::size_t k) {
            const std::size_t lo = b + std::min(e - b, k * chunk), hi = b + std::min(e - b, (k + 1) * chunk);
            T acc = identity;
            for (std::size_t i = lo; i < hi; ++i) acc = combine(acc, map(i));
            partial[k] = acc;
        });
        T acc = identity;
        for (const T& p : partial) acc = combine(acc, p);
        return acc;
    }
    /// out[i] = in[0] + ... + in[i - 1] in two parallel passes; returns the total. `in` and `out` may be the same array.
    template <class T> T exclusive_scan(std::span<const T> in, std::span<T> out) const {
        return detail::blocked_exclusive_scan(*this, in, out);
    }
};
#endif

// A backend that is not compiled in still names a type, so that using it stops at a static_assert
// that says what to link, instead of "'omp' is not a member of 'dynbvh::exec'".
namespace detail {
template <class> inline constexpr bool backend_missing = false;
} // namespace detail
#if !defined(_OPENMP)
struct omp {
    template <class Backend = void> omp(int = 0) {
        static_assert(detail::backend_missing<Backend>,
                      "dynbvh::exec::omp needs OpenMP: link dynbvh::omp (or compile with -fopenmp)");
    }
};
#endif
#if !defined(DYNBVH_WITH_TBB)
struct tbb {
    template <class Backend = void> tbb(int = 0) {
        static_assert(detail::backend_missing<Backend>,
                      "dynbvh::exec::tbb needs oneTBB: link dynbvh::tbb (or define DYNBVH_WITH_TBB and link TBB::tbb)");
    }
};
#endif

#if defined(DYNBVH_WITH_TBB)
/// oneTBB backend. `threads == 0` uses TBB's default arena; otherwise a private arena of that many threads,
/// created on first use and shared by copies. One object may be used by several threads at once (builders
/// take it by const&): the arena is created exactly once (std::call_once).
struct tbb {
    /// Threads of a private arena; 0 (default): TBB's default arena.
    int threads = 0;

    tbb() = default;
    /// A backend running in a private arena of `n` threads (0: TBB's default arena).
    explicit tbb(int n) : threads(n) {}

    /// `threads`, or the current arena's max_concurrency() when it is 0.
    std::size_t concurrency() const {
        return static_cast<std::size_t>(threads > 0 ? threads : ::tbb::this_task_arena::max_concurrency());
    }

    /// f(i) for i in [b, e) with tbb::parallel_for (`grain`: the blocked_range grain size).
    template <class F> void for_each(std::size_t b, std::size_t e, F&& f, std::size_t grain = 1024) const {
        if (e <= b) return;
        run([&] {
            ::tbb::parallel_for(::tbb::blocked_range<std::size_t>(b, e, std::max<std::size_t>(grain, 1)),
                                [&](const ::tbb::blocked_range<std::size_t>& r) {
                                    for (std::size_t i = r.begin(); i < r.end(); ++i) f(i);
                                });
        });
    }
    /// f(lo, hi) over the chunks tbb::parallel_for splits [b, e) into (`grain`: the blocked_range grain size).
    template <class F> void for_blocks(std::size_t b, std::size_t e, F&& f, std::size_t grain = 1024) const {
        if (e <= b) return;
        run([&] {
            ::tbb::parallel_for(::tbb::blocked_range<std::size_t>(b, e, std::max<std::size_t>(grain, 1)),
                                [&](const ::tbb::blocked_range<std::size_t>& r) { f(r.begin(), r.end()); });
        });
    }
    /// f(k) for k in [0, n) in parallel.
    template <class F> void for_tasks(std::size_t n, F&& f) const {
        run([&] {
            ::tbb::parallel_for(std::size_t(0), n, [&](std::size_t k) { f(k); });
        });
    }
    /// tbb::parallel_deterministic_reduce of map(i) over [b, e) with `combine` (associative): ranges of at
    /// most 1024 indices reduced in order and combined in a fixed tree, so a floating-point reduction gives
    /// the same bits from run to run and for any thread count (what the refit-or-rebuild decisions need).
    template <class T, class Map, class Combine>
    T reduce(std::size_t b, std::size_t e, T identity, Map&& map, Combine&& combine) const {
        if (e <= b) return identity;
        T result = identity;
        run([&] {
            result = ::tbb::parallel_deterministic_reduce(
                ::tbb::blocked_range<std::size_t>(b, e, 1024), identity,
                [&](const ::tbb::blocked_range<std::size_t>& r, T acc) {
                    for (std::size_t i = r.begin(); i < r.end(); ++i) acc = combine(acc, map(i));
                    return acc;
                },
                [&](const T& x, const T& y) { return combine(x, y); });
        });
        return result;
    }
    /// out[i] = in[0] + ... + in[i - 1] in two parallel passes; returns the total. `in` and `out` may be the same array.
    template <class T> T exclusive_scan(std::span<const T> in, std::span<T> out) const {
        return detail::blocked_exclusive_scan(*this, in, out);
    }

private:
    /// The arena, created once; the state itself exists from construction on, so concurrent first
    /// calls never race on the pointer (only on the once_flag, which is made for that).
    struct Arena {
        std::once_flag once;
        std::optional<::tbb::task_arena> arena;
    };
    template <class F> void run(F&& f) const {
        if (threads <= 0) { f(); return; }
        std::call_once(state_->once, [&] { state_->arena.emplace(threads); });
        state_->arena->execute(f);
    }
    std::shared_ptr<Arena> state_ = std::make_shared<Arena>();
};
#endif

/// The least a backend offers (a check for backends of your own). Builders take any type with the
/// six primitives above and are not constrained on this concept.
template <class E>
concept Executor = requires(const E& e) {
    { e.concurrency() } -> std::convertible_to<std::size_t>;
};

/// The best backend compiled in: omp when OpenMP is enabled, else serial.
#if defined(_OPENMP)
using default_executor = omp;
#else
using default_executor = serial;
#endif

} // namespace dynbvh::exec
