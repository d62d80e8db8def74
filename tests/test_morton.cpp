// detail/morton.hpp: Morton encodings and the quantisation grid.
#include "support.hpp"

#include <dynbvh/detail/morton.hpp>

using namespace dynbvh;
using namespace dynbvh::test;

TEST_CASE("morton: encode30 and encode63 equal a bit-by-bit interleave") {
    Rng r(7);
    for (int k = 0; k < 10000; ++k) {
        const std::uint32_t x = r.next() & 1023, y = r.next() & 1023, z = r.next() & 1023;
        std::uint32_t ref = 0;
        for (int b = 0; b < 10; ++b)
            ref |= ((x >> b & 1u) << (3 * b + 2)) | ((y >> b & 1u) << (3 * b + 1)) | ((z >> b & 1u) << (3 * b));
        REQUIRE(morton::encode30(x, y, z) == ref);
        const std::uint64_t X = r.next() & 0x1fffff, Y = r.next() & 0x1fffff, Z = r.next() & 0x1fffff;
        std::uint64_t ref64 = 0;
        for (int b = 0; b < 21; ++b)
            ref64 |= ((X >> b & 1ull) << (3 * b + 2)) | ((Y >> b & 1ull) << (3 * b + 1)) | ((Z >> b & 1ull) << (3 * b));
        REQUIRE(morton::encode63(X, Y, Z) == ref64);
    }
}

TEST_CASE("morton: quantiser cells for flat, point-sized and empty bounds, NaN and out-of-range points clamp into the grid") {
    // flat in z: every code must have z bits 0, and x/y still spread over the grid
    AABBf flat{{0, 0, 5}, {1, 2, 5}};
    morton::Quantizer<float> q(flat, 10);
    CHECK(q.cell({1, 2, 5}, 0) == 1023);
    CHECK(q.cell({1, 2, 5}, 1) == 1023);
    CHECK(q.cell({1, 2, 5}, 2) == 0);
    CHECK(q.cell({0.5f, 1, 5}, 0) == 512);
    // a point-sized box quantises everything to cell 0
    morton::Quantizer<float> p(AABBf{{3, 3, 3}, {3, 3, 3}}, 21);
    CHECK(morton::encode<std::uint64_t>(p, Vec3f{3, 3, 3}) == 0);
    // NaN and out-of-range points clamp into the grid
    CHECK(q.cell({std::nanf(""), 0, 0}, 0) == 0);
    CHECK(q.cell({-7, 99, 5}, 0) == 0);
    CHECK(q.cell({-7, 99, 5}, 1) == 1023);
    // empty bounds
    morton::Quantizer<float> e(AABBf{}, 10);
    CHECK(e.cell({1, 1, 1}, 0) == 0);
}
