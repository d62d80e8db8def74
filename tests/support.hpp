// Shared helpers for the tests: deterministic scene generators, an executor list,
// and an independent structural check of a Bvh.
#pragma once

#include <doctest/doctest.h>

#include <cmath>
#include <cstdint>
#include <filesystem>
#include <numbers>
#include <string>
#include <tuple>
#include <vector>

#include <dynbvh/bvh.hpp>
#include <dynbvh/executor.hpp>

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
template <class F> void for_each_executor(F&& f) {
    std::apply([&](auto... ex) { (f(ex), ...); }, executors());
}
template <class E> const char* executor_name() {
    if constexpr (std::is_same_v<E, exec::serial>) return "serial";
#if defined(_OPENMP)
    else if constexpr (std::is_same_v<E, exec::omp>) return "omp";
#endif
    else return "tbb";
}

/// Independent structure check, written without using any library traversal code:
/// every node reached once from the root, children adjacent and in range, parents contain
/// children, leaves contain their triangles' boxes (or, for fragments, overlap them), each
/// finite triangle referenced (exactly once when `single` is true), depth equals bvh.depth
/// and stays within max_depth. Returns an empty string when all holds.
template <class B>
std::string structure_problems(const B& bvh, std::span<const Trianglef> tris, bool single = true) {
    std::string why;
    auto fail = [&](const std::string& s) { if (why.size() < 2000) why += s + "\n"; };
    if (bvh.nodes.empty()) {
        for (const auto& t : tris)
            if (t.is_finite()) { fail("empty tree but a finite triangle exists"); break; }
        return why;
    }
    std::vector<int> visits(bvh.nodes.size(), 0);
    std::vector<int> refs(tris.size(), 0);
    std::vector<std::pair<std::size_t, std::uint32_t>> stack{{0, 0}};
    std::uint32_t deepest = 0;
    while (!stack.empty()) {
        const auto [i, d] = stack.back();
        stack.pop_back();
        if (++visits[i] > 1) { fail("node " + std::to_string(i) + " reached twice"); continue; }
        deepest = std::max(deepest, d);
        const auto& n = bvh.nodes[i];
        if (n.is_leaf()) {
            if (std::size_t(n.index) + n.count > bvh.prim_ids.size()) { fail("leaf range out of bounds"); continue; }
            std::vector<std::uint32_t> in_leaf;
            for (std::size_t s = n.index; s < std::size_t(n.index) + n.count; ++s) {
                const auto p = bvh.prim_ids[s];
                if (p >= tris.size()) { fail("prim id out of range"); continue; }
                in_leaf.push_back(p);
                ++refs[p];
                const auto tb = tris[p].bounds();
                const auto ov = intersection(n.bounds(), tb);
                if (single ? !n.bounds().contains(tb) : ov.is_empty())
                    fail("leaf " + std::to_string(i) + " does not hold triangle " + std::to_string(p));
                if constexpr (B::precomputed)
                    if (!(bvh.leaf_triangles[s].p0 == tris[p].p0 && bvh.leaf_triangles[s].p2 == tris[p].p2))
                        fail("precomputed triangle differs");
            }
            std::sort(in_leaf.begin(), in_leaf.end());
            if (std::adjacent_find(in_leaf.begin(), in_leaf.end()) != in_leaf.end()) fail("a triangle twice in one leaf");
        } else {
            if (std::size_t(n.index) + 1 >= bvh.nodes.size() || n.index == 0) { fail("child index out of range"); continue; }
            for (auto c : {n.left(), n.right()}) {
                if (!n.bounds().contains(bvh.nodes[c].bounds())) fail("node " + std::to_string(i) + " does not contain child");
                stack.push_back({c, d + 1});
            }
        }
    }
    for (std::size_t i = 0; i < visits.size(); ++i)
        if (visits[i] != 1) { fail("node " + std::to_string(i) + " visited " + std::to_string(visits[i]) + " times"); break; }
    std::size_t excluded = 0;
    for (std::size_t p = 0; p < tris.size(); ++p) {
        if (!tris[p].is_finite()) { ++excluded; if (refs[p]) fail("non-finite triangle referenced"); continue; }
        if (refs[p] == 0) fail("triangle " + std::to_string(p) + " unreachable");
        if (single && refs[p] > 1) fail("triangle " + std::to_string(p) + " referenced " + std::to_string(refs[p]) + " times");
    }
    if (excluded != bvh.excluded) fail("excluded count " + std::to_string(bvh.excluded) + " != " + std::to_string(excluded));
    if (deepest != bvh.depth) fail("depth " + std::to_string(bvh.depth) + " != measured " + std::to_string(deepest));
    if (bvh.depth > max_depth) fail("depth beyond max_depth");
    return why;
}

} // namespace dynbvh::test
