// detail/radix_sort.hpp: the parallel radix sort against std::stable_sort.
#include "support.hpp"

#include <algorithm>

#include <dynbvh/detail/radix_sort.hpp>

using namespace dynbvh;
using namespace dynbvh::test;

TEST_CASE("radix_sort: equals std::stable_sort on every executor, 32- and 64-bit keys") {
    for_each_executor([](auto ex) {
        CAPTURE(executor_name<decltype(ex)>());
        for (std::size_t n : {0u, 1u, 2u, 1000u, 300000u}) {
            Rng r(n + 1);
            std::vector<std::uint32_t> k(n), v(n);
            std::vector<std::uint64_t> k64(n);
            for (std::size_t i = 0; i < n; ++i) {
                k[i] = std::uint32_t(r.next() & ((1u << 30) - 1)) & 0x3ff00fffu;   // some constant digits: skipped passes
                k64[i] = r.next() >> 1;
                v[i] = std::uint32_t(i);
            }
            std::vector<std::pair<std::uint32_t, std::uint32_t>> ref(n);
            for (std::size_t i = 0; i < n; ++i) ref[i] = {k[i], v[i]};
            std::stable_sort(ref.begin(), ref.end(), [](auto a, auto b) { return a.first < b.first; });
            auto v64 = v;
            std::vector<std::pair<std::uint64_t, std::uint32_t>> ref64(n);
            for (std::size_t i = 0; i < n; ++i) ref64[i] = {k64[i], v64[i]};
            std::stable_sort(ref64.begin(), ref64.end(), [](auto a, auto b) { return a.first < b.first; });
            radix_sort(k, v, ex, 30);
            radix_sort(k64, v64, ex, 63);
            bool ok = true, ok64 = true;
            for (std::size_t i = 0; i < n; ++i) {
                ok = ok && k[i] == ref[i].first && v[i] == ref[i].second;
                ok64 = ok64 && k64[i] == ref64[i].first && v64[i] == ref64[i].second;
            }
            CHECK(ok);
            CHECK(ok64);
        }
    });
}
