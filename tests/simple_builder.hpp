// Test-only BVH constructions that do not depend on any library builder: a serial median-split
// builder (so traversal, SAH and validation can be tested on their own) and a deliberately deep
// "caterpillar" tree. Both produce the library's Bvh layout: root at 0, siblings adjacent.
#pragma once

#include <dynbvh/bvh.hpp>

#include <algorithm>
#include <cstdint>
#include <numeric>
#include <span>
#include <vector>

namespace dynbvh::test {

template <class NodeT, class Prim>
void finish_leaf_triangles(Bvh<NodeT, Prim>& bvh, std::span<const Triangle<typename NodeT::scalar_type>> tris) {
    if constexpr (Bvh<NodeT, Prim>::precomputed) {
        bvh.leaf_triangles.clear();
        for (auto id : bvh.prim_ids) bvh.leaf_triangles.push_back(tris[id]);
    }
}

/// Median split on the largest centroid axis until at most `leaf_size` triangles; non-finite triangles
/// are excluded and counted.
template <class NodeT = Node<>, class Prim = prim::indexed>
Bvh<NodeT, Prim> median_build(std::span<const Triangle<typename NodeT::scalar_type>> tris, std::size_t leaf_size = 4) {
    using T = typename NodeT::scalar_type;
    using Index = typename NodeT::index_type;
    Bvh<NodeT, Prim> bvh;
    bvh.primitive_count = tris.size();
    std::vector<Index> ids;
    for (std::size_t i = 0; i < tris.size(); ++i) {
        if (tris[i].is_finite()) ids.push_back(Index(i));
        else ++bvh.excluded;
    }
    if (ids.empty()) return bvh;
    bvh.nodes.emplace_back();
    struct Job {
        std::size_t node, begin, end;
        std::uint32_t depth;
    };
    std::vector<Job> jobs{{0, 0, ids.size(), 0}};
    while (!jobs.empty()) {
        const Job j = jobs.back();
        jobs.pop_back();
        AABB<T> box, cbox;
        for (std::size_t i = j.begin; i < j.end; ++i) {
            box.extend(tris[ids[i]].bounds());
            cbox.extend(tris[ids[i]].centroid());
        }
        bvh.nodes[j.node].set_bounds(box);
        if (j.end - j.begin <= leaf_size) {
            bvh.nodes[j.node].index = Index(bvh.prim_ids.size());
            bvh.nodes[j.node].count = Index(j.end - j.begin);
            for (std::size_t i = j.begin; i < j.end; ++i) bvh.prim_ids.push_back(ids[i]);
            bvh.depth = std::max(bvh.depth, j.depth);
            continue;
        }
        const int axis = largest_axis(cbox.diagonal());
        const std::size_t mid = (j.begin + j.end) / 2;
        std::nth_element(ids.begin() + std::ptrdiff_t(j.begin), ids.begin() + std::ptrdiff_t(mid),
                         ids.begin() + std::ptrdiff_t(j.end), [&](Index a, Index b) {
                             const T ca = tris[a].centroid()[std::size_t(axis)], cb = tris[b].centroid()[std::size_t(axis)];
                             return ca < cb || (ca == cb && a < b);
                         });
        const std::size_t c = bvh.nodes.size();
        bvh.nodes.resize(c + 2);
        bvh.nodes[j.node].index = Index(c);
        bvh.nodes[j.node].count = 0;
        jobs.push_back({c + 1, mid, j.end, j.depth + 1});
        jobs.push_back({c, j.begin, mid, j.depth + 1});
    }
    finish_leaf_triangles(bvh, tris);
    return bvh;
}

/// `levels` equal triangles stacked along z (z = 0, 1, ...): with caterpillar_build, a tree deeper than
/// max_depth even for 8-wide nodes (about 7 binary levels per node) when levels = 600.
inline std::vector<Trianglef> stacked_triangles(int levels) {
    std::vector<Trianglef> tris;
    for (int i = 0; i < levels; ++i) {
        const float z = float(i);
        tris.push_back({{-1, -1, z}, {3, -1, z}, {-1, 3, z}});
    }
    return tris;
}

/// Every inner node has a one-triangle leaf on the left and the rest on the right: depth n - 1.
template <class NodeT = Node<>, class Prim = prim::indexed>
Bvh<NodeT, Prim> caterpillar_build(std::span<const Triangle<typename NodeT::scalar_type>> tris) {
    using T = typename NodeT::scalar_type;
    using Index = typename NodeT::index_type;
    Bvh<NodeT, Prim> bvh;
    bvh.primitive_count = tris.size();
    const std::size_t n = tris.size();
    if (n == 0) return bvh;
    // suffix boxes
    std::vector<AABB<T>> suffix(n + 1);
    for (std::size_t i = n; i-- > 0;) suffix[i] = merge(suffix[i + 1], tris[i].bounds());
    bvh.nodes.emplace_back();
    std::size_t cur = 0;
    for (std::size_t i = 0; i < n; ++i) {
        bvh.nodes[cur].set_bounds(suffix[i]);
        if (i + 1 == n) {
            bvh.nodes[cur].index = Index(bvh.prim_ids.size());
            bvh.nodes[cur].count = 1;
            bvh.prim_ids.push_back(Index(i));
            break;
        }
        const std::size_t c = bvh.nodes.size();
        bvh.nodes.resize(c + 2);
        bvh.nodes[cur].index = Index(c);
        bvh.nodes[cur].count = 0;
        bvh.nodes[c].set_bounds(tris[i].bounds());
        bvh.nodes[c].index = Index(bvh.prim_ids.size());
        bvh.nodes[c].count = 1;
        bvh.prim_ids.push_back(Index(i));
        cur = c + 1;
    }
    bvh.depth = std::uint32_t(n - 1);
    finish_leaf_triangles(bvh, tris);
    return bvh;
}

} // namespace dynbvh::test
