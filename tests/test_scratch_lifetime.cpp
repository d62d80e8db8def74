// Scratch cache lifetime (scratch.hpp, issue 16.1): objects of static storage duration that hold
// scratch blocks (>= ScratchPool::min_cached, the cached size) are destroyed at exit in any order relative to the cache.
// The objects below are constructed before the cache is first used (namespace scope, empty), so with
// a function-local cache they are destroyed after it and return their blocks to a dead object: under
// AddressSanitizer that is a heap-use-after-free at exit, i.e. this program's exit status is the check
// (ctest fails it). The test cases also check the trees, so the unsanitized run is not empty.
#include <doctest/doctest.h>

#include <dynbvh/lbvh.hpp>
#include <dynbvh/refit.hpp>
#include <dynbvh/detail/scratch.hpp>
#include <dynbvh/traverse.hpp>
#include <dynbvh/validate.hpp>
#include <dynbvh/wide.hpp>

#include <cstddef>
#include <memory>
#include <vector>

#include "support.hpp"

using namespace dynbvh;

namespace {

// Namespace-scope holders of every kind of scratch-backed array (destroyed after main returns).
Bvh<> g_indexed;
Bvh<Node<>, prim::copied> g_precomputed;   // also holds leaf_triangles
WideBvh<> g_wide;
scratch_vector<std::uint32_t> g_vector;
std::unique_ptr<Bvh<>> g_heap;                   // a heap tree owned by a static: freed at exit too

constexpr std::size_t n_tris = 40000;            // nodes: 2n * 32 bytes >= the cache threshold (min_cached)

} // namespace

TEST_CASE("scratch: trees held in statics are assigned in a test and freed at exit") {
    const auto tris = test::random_soup(n_tris, 16);
    g_indexed = lbvh::build(tris);
    REQUIRE(g_indexed.nodes.size() * sizeof(Node<>) >= detail::ScratchPool::min_cached);
    CHECK(validate(g_indexed, tris).ok());
    g_precomputed = lbvh::build<Node<>, prim::copied>(tris);
    REQUIRE(g_precomputed.leaf_triangles.size() * sizeof(Trianglef) >= detail::ScratchPool::min_cached);
    CHECK(validate(g_precomputed, tris).ok());
    g_wide = make_wide(g_indexed);
    REQUIRE(g_wide.nodes.size() * sizeof(WideNode<>) >= detail::ScratchPool::min_cached);
    g_vector.resize(std::size_t(1) << 19);        // 2 MiB
    g_heap = std::make_unique<Bvh<>>(lbvh::build(tris));
    refit(*g_heap, tris);
    CHECK(validate(*g_heap, tris).ok());
    // A block returned now is cached and handed out again: the cache works before exit as well.
    {
        Bvh<> tmp = lbvh::build(tris);
        (void)tmp;
    }
    CHECK(scratch_cached_bytes() >= detail::ScratchPool::min_cached);
}

TEST_CASE("scratch: release_scratch while statics still hold blocks, then more builds") {
    release_scratch();
    CHECK(scratch_cached_bytes() == 0);
    const auto tris = test::random_soup(n_tris, 17);
    Bvh<> local = lbvh::build(tris);
    CHECK(validate(local, tris).ok());
    CHECK(!g_indexed.empty());   // the statics are untouched; they are freed after main
}

TEST_CASE("scratch: the cache threshold applies to the rounded size (min_cached / 4 - 1 uint32s are cached and reused)") {
    static_assert(detail::ScratchPool::min_cached % 64 == 0 && detail::ScratchPool::min_cached >= 128);
    release_scratch();
    // min_cached - 4 bytes: exactly min_cached once rounded to 64 bytes
    constexpr std::size_t n = detail::ScratchPool::min_cached / sizeof(std::uint32_t) - 1;
    constexpr std::size_t block = detail::ScratchPool::block_size(detail::ScratchPool::min_cached);
    static_assert(block == detail::ScratchPool::min_cached / 8 * 9);
    { scratch_vector<std::uint32_t> v(n); }
    CHECK(scratch_cached_bytes() == block);   // returned to the cache, at its real size (an eighth more room)
    {
        scratch_vector<std::uint32_t> v(n);
        CHECK(scratch_cached_bytes() == 0);   // the next frame's array of the same size comes from the cache
    }
    CHECK(scratch_cached_bytes() == block);
    {
        scratch_vector<std::uint32_t> v(block / sizeof(std::uint32_t));   // a request that needs the whole margin fits too
        CHECK(scratch_cached_bytes() == 0);
    }
    CHECK(scratch_cached_bytes() == block);
    // Below the threshold once rounded (min_cached - 64 bytes): not cached, freed.
    release_scratch();
    { scratch_vector<std::uint32_t> v(n - 16); }
    CHECK(scratch_cached_bytes() == 0);
}
