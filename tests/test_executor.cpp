// executor.hpp: every executor's parallel steps agree with serial loops.
#include "hit_compare.hpp"
#include "support.hpp"

#include <algorithm>

#include <dynbvh/executor.hpp>

using namespace dynbvh;
using namespace dynbvh::test;

TEST_CASE("executors: for_each, for_blocks, reduce and exclusive_scan (also in place) agree with serial loops") {
    for_each_executor([](auto ex) {
        CAPTURE(executor_name<decltype(ex)>());
        for (std::size_t n : {0u, 1u, 7u, 1000u, 100000u}) {
            std::vector<std::uint64_t> v(n), out(n), ref(n);
            ex.for_each(0, n, [&](std::size_t i) { v[i] = (i * 2654435761u) % 1000; });
            std::uint64_t sum = 0;
            for (std::size_t i = 0; i < n; ++i) { ref[i] = sum; sum += v[i]; }
            const auto total = ex.exclusive_scan(std::span<const std::uint64_t>(v), std::span<std::uint64_t>(out));
            CHECK(total == sum);
            CHECK(out == ref);
            // in place
            auto w = v;
            ex.exclusive_scan(std::span<const std::uint64_t>(w), std::span<std::uint64_t>(w));
            CHECK(w == ref);
            const auto r = ex.reduce(std::size_t(0), n, std::uint64_t(0), [&](std::size_t i) { return v[i]; },
                                     [](std::uint64_t a, std::uint64_t b) { return a + b; });
            CHECK(r == sum);
            std::vector<int> hits(n, 0);
            ex.for_blocks(0, n, [&](std::size_t lo, std::size_t hi) { for (auto i = lo; i < hi; ++i) ++hits[i]; });
            CHECK(std::all_of(hits.begin(), hits.end(), [](int h) { return h == 1; }));
        }
    });
}

TEST_CASE("executors: a floating-point reduce gives the same bits on every call (refit_sah's SAH depends on it)") {
    // Terms of very different magnitudes, so a different association order would round differently.
    const std::size_t n = 300000;
    std::vector<double> v(n);
    for (std::size_t i = 0; i < n; ++i) v[i] = double((i * 2654435761u) % 1000003) * (i % 3 == 0 ? 1e-9 : 1e3);
    for_each_executor([&](auto ex) {
        CAPTURE(executor_name<decltype(ex)>());
        const auto sum = [&] {
            return ex.reduce(std::size_t(0), n, 0.0, [&](std::size_t i) { return v[i]; }, [](double a, double b) { return a + b; });
        };
        const double first = sum();
        bool same = true;
        for (int rep = 0; rep < 20; ++rep) same = same && same_bits(sum(), first);
        CHECK(same);
        long double exact = 0;
        for (double x : v) exact += x;
        CHECK(first == doctest::Approx(double(exact)).epsilon(1e-12));
    });
}
