// SPDX-License-Identifier: MIT
/// @file detail/sah_top.hpp
/// The top of a raw binary tree rebuilt by binned SAH over its subtrees: HLBVH (Pantaleoni and Luebke
/// 2010, "HLBVH: Hierarchical LBVH Construction for Real-Time Ray Tracing of Dynamic Geometry"; the
/// SAH over clusters as in Garanzha, Pantaleoni and McAllister 2011). An LBVH's upper levels split at
/// the planes of the Morton grid, wherever the triangles are; they span most of the scene, so their
/// poor splits cost every ray. Its lower levels are small and good. Here every subtree of at most
/// `cluster_refs` references (or emitted as one leaf) whose parent is larger becomes a cluster; the
/// inner nodes above the clusters are rebuilt top down by binned SAH over the clusters' boxes (their
/// centres binned, 32 bins per axis, each cluster weighted by its references: detail/sah_bins.hpp),
/// reusing the same node ids, and their facts are recomputed with the builder's CollapseRule.
///
/// Work: K clusters (about 2-4 n / cluster_refs) binned O(K log K) in all; the top ranges are split
/// serially until they hold at most 512 clusters, then one task builds each such range and its
/// facts. Deterministic: the splits and the node ids they take depend on the clusters alone, so the
/// tree is the same on every executor and thread count.
#pragma once

#include <algorithm>
#include <array>
#include <cstdint>
#include <span>
#include <vector>

#include "../aabb.hpp"
#include "emit.hpp"
#include "references.hpp"
#include "sah_bins.hpp"

namespace dynbvh::detail {

/// A subtree kept whole: its raw id (inner node or leaf-flagged reference), box and references.
template <class T>
struct TopCluster {
    AABB<T> box;
    std::uint32_t id;
    std::uint32_t refs;
};

/// One range of clusters [begin, end) to be split: its node takes ids[slot] (its descendants the next
/// end - begin - 2 slots) and is linked from *link.
struct TopRange {
    std::uint32_t begin, end, slot;
    std::uint32_t* link;
};

/// Splits range `r` (at least 2 clusters) by binned SAH, writes its node's links and returns its two
/// children's ranges. A range whose centres coincide, or whose bins put every cluster on one side,
/// is split in the middle of its current order.
template <class T>
std::array<TopRange, 2> split_top_range(BinaryTree& tree, std::span<TopCluster<T>> clusters, std::span<const std::uint32_t> ids,
                                        const TopRange& r, Bins<T>& bins, std::vector<double>& right) {
    constexpr std::uint32_t k = 32;
    TopCluster<T>* c = clusters.data() + r.begin;
    const std::uint32_t n = r.end - r.begin;
    AABB<T> centres;
    for (std::uint32_t i = 0; i < n; ++i) centres.extend(c[i].box.center());
    const Binner<T> binner(centres, k);
    bins.reset(k);
    for (std::uint32_t i = 0; i < n; ++i) {
        const Vec3<T> m = c[i].box.center();
        for (std::size_t a = 0; a < 3; ++a) {
            const std::size_t b = a * k + binner.bin(m, a);
            bins.count[b] += c[i].refs;   // weight: the references below (cheaper sides hold fewer)
            bins.box[b].extend(c[i].box);
        }
    }
    const Split s = best_split(bins, centres, right);
    std::uint32_t mid = n / 2;
    if (s.axis >= 0) {
        const auto a = std::size_t(s.axis);
        mid = std::uint32_t(std::partition(c, c + n, [&](const TopCluster<T>& x) { return binner.bin(x.box.center(), a) < s.bin; }) - c);
        if (mid == 0 || mid == n) mid = n / 2;   // not reached (both sides weigh > 0), kept as a guard
    }
    const std::uint32_t node = ids[r.slot];
    *r.link = node;
    return {TopRange{r.begin, r.begin + mid, r.slot + 1, &tree.left[node]},
            TopRange{r.begin + mid, r.end, r.slot + mid, &tree.right[node]}};
}

/// Builds range `r` completely (explicit stack), appending the slots of the nodes it makes to `made`
/// in creation order (a node before its descendants).
template <class T>
void build_top_range(BinaryTree& tree, std::span<TopCluster<T>> clusters, std::span<const std::uint32_t> ids, const TopRange& r,
                     std::uint32_t serial_above, std::vector<TopRange>& pending, std::vector<std::uint32_t>& made) {
    Bins<T> bins(32);
    std::vector<double> right;
    std::vector<TopRange> stack{r};
    while (!stack.empty()) {
        const TopRange t = stack.back();
        stack.pop_back();
        if (t.end - t.begin == 1) { *t.link = clusters[t.begin].id; continue; }
        if (t.end - t.begin <= serial_above) { pending.push_back(t); continue; }
        made.push_back(t.slot);
        const auto kids = split_top_range(tree, clusters, ids, t, bins, right);
        stack.push_back(kids[1]);
        stack.push_back(kids[0]);
    }
}

/// Rebuilds the top of `tree` by binned SAH over its subtrees of at most `cluster_refs` references (see
/// the file comment). `info` holds the facts of every inner node under `rule` (as a bottom-up builder
/// leaves them) and is updated for the rebuilt nodes. The references and the subtrees below the
/// clusters are untouched. Nothing changes when the root is a cluster itself.
template <class T, class Exec>
void rebuild_top_by_sah(BinaryTree& tree, const References<T>& refs, const CollapseRule<T>& rule, std::span<RawNodeInfo<T>> info,
                        std::uint32_t cluster_refs, const Exec& ex) {
    const auto is_top = [&](std::uint32_t id) {
        return !BinaryTree::is_leaf(id) && !info[id].collapsed && info[id].refs > cluster_refs;
    };
    if (!is_top(tree.root)) return;
    // Step 1: the nodes above the clusters (their ids are reused) and the clusters, depth first.
    std::vector<std::uint32_t> ids;
    std::vector<TopCluster<T>> clusters;
    std::vector<std::uint32_t> stack{tree.root};
    while (!stack.empty()) {
        const std::uint32_t id = stack.back();
        stack.pop_back();
        ids.push_back(id);
        for (const std::uint32_t c : {tree.right[id], tree.left[id]}) {
            if (is_top(c)) { stack.push_back(c); continue; }
            if (BinaryTree::is_leaf(c)) clusters.push_back({refs.box[BinaryTree::ref_of(c)], c, 1u});
            else clusters.push_back({info[c].box(), c, info[c].refs});
        }
    }
    if (clusters.size() < 3) return;   // one node above two clusters: nothing to choose
    const auto all = std::span<TopCluster<T>>(clusters);
    const auto slots = std::span<const std::uint32_t>(ids);
    // Step 2: the top ranges serially, until they hold at most `task` clusters.
    constexpr std::uint32_t task = 512;
    std::vector<TopRange> tasks;
    std::vector<std::uint32_t> serial_made;
    build_top_range(tree, all, slots, TopRange{0, std::uint32_t(clusters.size()), 0, &tree.root}, task, tasks, serial_made);
    // Step 3: each task's range, then its nodes' facts (descendants take later slots: reverse order).
    ex.for_tasks(tasks.size(), [&](std::size_t k) {
        std::vector<TopRange> none;
        std::vector<std::uint32_t> made;
        build_top_range(tree, all, slots, tasks[k], 0, none, made);
        for (auto s = made.rbegin(); s != made.rend(); ++s) rule.node(tree, refs, info.data(), ids[*s]);
    });
    // Step 4: the serial nodes' facts, in reverse creation order (children first).
    for (auto s = serial_made.rbegin(); s != serial_made.rend(); ++s) rule.node(tree, refs, info.data(), ids[*s]);
}

} // namespace dynbvh::detail
