// Shared helpers for the tests: deterministic scene generators, an executor list,
// and an independent structural check of a Bvh.
#pragma once

#include <doctest/doctest.h>

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <cstdlib>
#include <cstring>
#include <filesystem>
#include <limits>
#include <numbers>
#include <random>
#include <string>
#include <tuple>
#include <vector>

#include <dynbvh/bvh.hpp>
#include <dynbvh/detail/emit.hpp>
#include <dynbvh/executor.hpp>
#include <dynbvh/validate.hpp>

#include "builds.hpp"  // shared builder instantiations, compiled once
#include "sanitized.hpp"

namespace dynbvh::test {

/// splitmix64: identical output on every platform (std:: distributions are not).
struct Rng {
    std::uint64_t s;
    explicit Rng(std::uint64_t seed) : s(seed) {}
    std::uint64_t next() {
        std::uint64_t z = (s += 0x9e3779b97f4a7c15ull);
        z = (z ^ (z >> 30)) * 0xbf58476d1ce4e5b9ull;
        z = (z ^ (z >> 27)) * 0x94d049bb133111ebull;
        return z ^ (z >> 31);
    }
    float uniform() { return float(next() >> 40) * (1.0f / 16777216.0f); }   // [0, 1)
    float uniform(float lo, float hi) { return lo + (hi - lo) * uniform(); }
};

/// n small random triangles in the unit cube.
inline std::vector<Trianglef> random_soup(std::size_t n, std::uint64_t seed = 1, float size = 0.02f) {
    Rng r(seed);
    std::vector<Trianglef> t(n);
    for (auto& tri : t) {
        const Vec3f c{r.uniform(), r.uniform(), r.uniform()};
        auto jitter = [&] { return Vec3f{r.uniform(-size, size), r.uniform(-size, size), r.uniform(-size, size)}; };
        tri = {c + jitter(), c + jitter(), c + jitter()};
    }
    return t;
}

/// UV sphere of radius 1 at the origin: 2 * stacks * slices triangles (closed, watertight indexing).
inline std::vector<Trianglef> sphere(int stacks = 64, int slices = 128) {
    auto point = [&](int i, int j) {
        const double th = std::numbers::pi * i / stacks, ph = 2 * std::numbers::pi * (j % slices) / slices;
        return Vec3f{float(std::sin(th) * std::cos(ph)), float(std::cos(th)), float(std::sin(th) * std::sin(ph))};
    };
    std::vector<Trianglef> t;
    for (int i = 0; i < stacks; ++i)
        for (int j = 0; j < slices; ++j) {
            const Vec3f a = point(i, j), b = point(i + 1, j), c = point(i + 1, j + 1), d = point(i, j + 1);
            t.push_back({a, b, c});
            t.push_back({a, c, d});
        }
    return t;
}

/// Random triangles all in the plane z = 0.
inline std::vector<Trianglef> flat_scene(std::size_t n, std::uint64_t seed = 2) {
    auto t = random_soup(n, seed);
    for (auto& tri : t) tri.p0.z = tri.p1.z = tri.p2.z = 0;
    return t;
}

/// n copies of one triangle (all centroids identical).
inline std::vector<Trianglef> identical(std::size_t n) {
    return std::vector<Trianglef>(n, Trianglef{{0, 0, 0}, {1, 0, 0}, {0, 1, 0}});
}

/// Long thin diagonal triangles: the case presplitting is for.
inline std::vector<Trianglef> long_thin(std::size_t n, std::uint64_t seed = 3) {
    Rng r(seed);
    std::vector<Trianglef> t(n);
    for (auto& tri : t) {
        const Vec3f a{r.uniform(), r.uniform(), r.uniform()};
        const Vec3f b{r.uniform(), r.uniform(), r.uniform()};
        tri = {a, b, b + Vec3f{0.001f, 0.001f, 0}};
    }
    return t;
}

inline std::string data_path(const std::string& rel) { return std::string(DYNBVH_DATA_DIR) + "/" + rel; }
inline bool have_data(const std::string& rel) { return std::filesystem::exists(data_path(rel)); }


/// The executors this build has, as a tuple for templated checks.
inline auto executors() {
    return std::tuple<exec::serial
#if defined(_OPENMP)
                      , exec::omp
#endif
#if defined(DYNBVH_WITH_TBB)
                      , exec::tbb
#endif
                      >{};
}
/// Whether this build has executor E (executors() lists it).
template <class E>
inline constexpr bool has_executor =
    []<class... Es>(std::tuple<Es...>*) { return (std::is_same_v<E, Es> || ...); }(static_cast<decltype(executors())*>(nullptr));
template <class E> const char* executor_name() {
    if constexpr (std::is_same_v<E, exec::serial>) return "serial";
#if defined(_OPENMP)
    else if constexpr (std::is_same_v<E, exec::omp>) return "omp";
#endif
    else return "tbb";
}
/// Whether executor E is selected: all are, unless the environment variable DYNBVH_TEST_EXECUTORS
/// lists names, e.g. DYNBVH_TEST_EXECUTORS=serial,tbb (tools/tsan.sh uses it).
template <class E> bool executor_selected() {
    const char* list = std::getenv("DYNBVH_TEST_EXECUTORS");
    if (!list || !*list) return true;
    const std::string s = "," + std::string(list) + ",";
    return s.find("," + std::string(executor_name<E>()) + ",") != std::string::npos;
}
/// Calls f(executor) for every executor this build has (and DYNBVH_TEST_EXECUTORS selects).
template <class F> void for_each_executor(F&& f) {
    std::apply([&](auto... ex) { ((executor_selected<decltype(ex)>() ? (void)f(ex) : void()), ...); }, executors());
}

/// n small random triangles in the unit cube from std::mt19937 (the stream the builder tests were written
/// against; libstdc++'s mt19937 and uniform_real_distribution<float> are fixed for this toolchain).
inline std::vector<Trianglef> mt_soup(std::size_t n, std::uint32_t seed, float size = 0.02f) {
    std::mt19937 rng(seed);
    std::uniform_real_distribution<float> u(0.0f, 1.0f), v(-size, size);
    std::vector<Trianglef> tris(n);
    for (auto& t : tris) {
        const Vec3f o{u(rng), u(rng), u(rng)};
        t = {o, o + Vec3f{v(rng), v(rng), v(rng)}, o + Vec3f{v(rng), v(rng), v(rng)}};
    }
    return tris;
}

/// Checks the BinaryTree contract for n references: every inner node reached exactly once from the root,
/// every reference a leaf exactly once (so no cycles, nothing unreachable), and the raw depth at most
/// `depth_bound`. Returns the depth (edges).
inline std::size_t check_topology(const BinaryTree& tree, std::size_t n,
                                  std::size_t depth_bound = std::numeric_limits<std::size_t>::max()) {
    if (n == 0) {
        CHECK(tree.inner_count() == 0);
        return 0;
    }
    if (n == 1) {
        CHECK(tree.inner_count() == 0);
        CHECK(tree.root == BinaryTree::leaf(0));
        return 0;
    }
    REQUIRE(tree.inner_count() == n - 1);
    REQUIRE(tree.right.size() == n - 1);
    REQUIRE_FALSE(BinaryTree::is_leaf(tree.root));
    std::vector<std::uint8_t> inner_seen(n - 1, 0), ref_seen(n, 0);
    std::vector<std::pair<std::uint32_t, std::size_t>> stack{{tree.root, 0}};
    std::size_t depth = 0, bad = 0;
    while (!stack.empty()) {
        const auto [id, d] = stack.back();
        stack.pop_back();
        depth = std::max(depth, d);
        if (BinaryTree::is_leaf(id)) {
            const std::uint32_t r = BinaryTree::ref_of(id);
            if (r >= n || ref_seen[r]++) ++bad;
            continue;
        }
        if (id >= n - 1 || inner_seen[id]++) {
            ++bad;
            continue;
        }
        stack.push_back({tree.left[id], d + 1});
        stack.push_back({tree.right[id], d + 1});
    }
    CHECK_MESSAGE(bad == 0, bad, " references or inner nodes out of range or reached twice");
    CHECK(std::count(inner_seen.begin(), inner_seen.end(), 1) == static_cast<std::ptrdiff_t>(n - 1));
    CHECK(std::count(ref_seen.begin(), ref_seen.end(), 1) == static_cast<std::ptrdiff_t>(n));
    CHECK(depth <= depth_bound);
    return depth;
}

/// validate() as a string: empty when the tree is valid, else the reasons (for CHECK(... == "")).
template <class B>
std::string structure_problems(const B& bvh, std::span<const Trianglef> tris, bool single = true) {
    const auto report = validate(bvh, tris, {.expect_single_reference = single});
    return report.ok() ? std::string() : report.summary();
}

/// Empty when two block trees are the same to the bit (nodes, blocks lane by lane, counts), else what differs.
template <class WA, class WB>
std::string block_difference(const WA& a, const WB& b) {
    if (a.nodes.size() != b.nodes.size() || a.blocks.size() != b.blocks.size()) return "sizes differ";
    if (a.depth != b.depth || a.primitive_count != b.primitive_count || a.excluded != b.excluded) return "depth or counts differ";
    if (!a.prim_ids.empty() || !b.prim_ids.empty() || !a.leaf_triangles.empty() || !b.leaf_triangles.empty()) return "a block tree with references";
    if (!a.nodes.empty() && std::memcmp(a.nodes.data(), b.nodes.data(), a.nodes.size() * sizeof(a.nodes[0])) != 0) return "nodes differ";
    for (std::size_t i = 0; i < a.blocks.size(); ++i)   // field by field: a block's tail padding is not written
        if (std::memcmp(a.blocks[i].v, b.blocks[i].v, sizeof a.blocks[i].v) != 0 ||
            std::memcmp(a.blocks[i].prim, b.blocks[i].prim, sizeof a.blocks[i].prim) != 0 || a.blocks[i].count != b.blocks[i].count)
            return "block " + std::to_string(i) + " differs";
    return {};
}

} // namespace dynbvh::test
