/// @file wide.hpp
/// A 4- or 8-wide BVH converted from any binary `Bvh`, and its single-ray traversal.
/// @code
///   auto bvh  = dynbvh::lbvh::build(tris, {}, ex);
///   auto wide = dynbvh::make_wide(std::move(bvh), ex);        // O(n), parallel over `ex` (or copy: make_wide(bvh, ex))
///   auto w8   = dynbvh::make_wide<8>(other_bvh, ex);          // 8 children per node (best with AVX, see below)
///   auto hit  = dynbvh::intersect(wide, tris, ray);           // same answer as intersect(bvh, ...)
///   bool occ  = dynbvh::occluded<dynbvh::trace::fast>(wide, tris, ray);
/// @endcode
///
/// Layout: a `WideNode<Scalar, Index, W>` (W = 4 by default, or 8) holds the boxes of up to W children in
/// structure-of-arrays form (lo_x[W], hi_x[W], lo_y[W], ...), so one traversal step tests all W boxes
/// with one SIMD instruction per slab plane. Each child slot is an inner node (count 0, `child` = node index),
/// a leaf (`child` = first slot of prim_ids, `count` references) or empty (an inverted box
/// +inf/-inf that every box test misses). WideNode<float, uint32_t> is 128 bytes (two cache lines,
/// 64-byte aligned): 32 bytes per child, as many as a binary node; the 8-wide node is 256 bytes. Leaves, prim_ids and the
/// precomputed triangles are the binary tree's, unchanged.
///
/// Collapse (after Wald et al. 2008 "Getting rid of packets", and Pinto 2010): each wide node starts
/// from a binary inner node's two children and repeatedly replaces the inner child of largest surface
/// area by its two children until it has W children or only leaves. Wide nodes are therefore a
/// subset of the binary inner nodes, with their boxes unchanged: leaf boxes and leaf contents are the
/// binary tree's, and the SAH of the wide tree (`sah_cost(WideBvh)`) has the same leaf term and a
/// smaller inner term. The conversion collapses the top serially and then 256 subtrees in parallel
/// tasks (two parallel steps), O(binary nodes) work, the same tree on every executor; it is a build
/// step and should be timed as one (a few tens of percent of an LBVH build, see bench_trace.cpp).
///
/// SIMD: with SSE2 (every x86-64 compiler; `__SSE2__` or MSVC's `_M_X64`) the four box tests of a
/// node use `<immintrin.h>` SSE intrinsics (FMA for box::fast when the compiler targets it); an 8-wide
/// node takes two SSE steps, or one AVX step when the compiler targets AVX (`__AVX__`, e.g. -mavx2 or
/// -march=native). Fewer, wider nodes mean fewer traversal steps per ray: on the bunny's primary rays
/// 2.1 nodes per ray instead of 2.75. Every
/// other target uses a scalar loop that calls the box policy's own `test_octant` for each slot:
/// the SSE and AVX paths perform the same IEEE operations in the same order (max/min operand order
/// chosen so that NaN and +-0 resolve as in detail::max_keep/min_keep), so all give the same hits. The
/// scalar path is also what `-DDYNBVH_NO_SIMD` selects (tests/test_wide.cpp passes either way). The
/// library does not choose instruction sets: the user's compiler flags do (-march=... enables FMA
/// and AVX). For float rays and box::robust, the per-ray setup (finite
/// and non-degenerate checks, 1 / dir, octant) is also done in SSE when it can give exactly
/// box::robust::prepared's values (no subnormal direction component), else through that struct. The
/// triangle test's setup waits for the first leaf: most primary rays of open scenes reach none.
///
/// Exactness: as in traverse.hpp. trace::robust's box test is box::robust (Ize 2013) evaluated on
/// four boxes at once with the same conservative exit margin, so `intersect(wide, ...)` returns what
/// `brute_force_intersect` returns (t to the bit; an exact tie may name another triangle), and the
/// same as `intersect(bvh, ...)` on the binary tree. Traversal visits the hit children nearest
/// first (the others go on a fixed stack with their entry distance and are skipped once a closer hit
/// is known). The stack holds W - 1 entries per wide level; a tree deeper than max_depth, or one whose
/// `depth` is wrong, is traced with a heap stack that cannot overflow.
#pragma once

#include <algorithm>
#include <bit>
#include <cstddef>
#include <cstdint>
#include <limits>
#include <new>
#include <span>
#include <type_traits>
#include <utility>
#include <vector>

#include "bvh.hpp"
#include "executor.hpp"
#include "intersect.hpp"
#include "sah.hpp"
#include "scratch.hpp"
#include "traverse.hpp"

#if (defined(__SSE2__) || defined(_M_X64)) && !defined(DYNBVH_NO_SIMD)
#include <immintrin.h>
#define DYNBVH_WIDE_SSE 1
#endif

namespace dynbvh {

/// One node of a 4-wide BVH: the boxes of up to four children, structure of arrays.
/// Slot k: `count[k] == 0` and a valid box: inner child, node `child[k]`; `count[k] > 0`: leaf of
/// `count[k]` references from prim_ids slot `child[k]`; inverted box (lo = +inf, hi = -inf): empty.
template <class Scalar = float, class Index = std::uint32_t, int W = 4>
struct alignas(64) WideNode {
    static_assert(std::is_floating_point_v<Scalar> && std::is_unsigned_v<Index>);
    static_assert(W == 4 || W == 8, "wide nodes have 4 or 8 children");
    using scalar_type = Scalar;
    using index_type = Index;
    static constexpr int width = W;

    Scalar lo_x[W], hi_x[W], lo_y[W], hi_y[W], lo_z[W], hi_z[W];
    Index child[W];
    Index count[W];

    /// Marks every slot empty.
    constexpr void clear() noexcept {
        constexpr Scalar inf = std::numeric_limits<Scalar>::infinity();
        for (int k = 0; k < W; ++k) {
            lo_x[k] = lo_y[k] = lo_z[k] = inf;
            hi_x[k] = hi_y[k] = hi_z[k] = -inf;
            child[k] = 0;
            count[k] = 0;
        }
    }
    constexpr bool empty_slot(int k) const noexcept { return !(lo_x[k] <= hi_x[k]); }
    constexpr bool is_leaf(int k) const noexcept { return count[k] != 0; }
    constexpr AABB<Scalar> bounds(int k) const noexcept { return {{lo_x[k], lo_y[k], lo_z[k]}, {hi_x[k], hi_y[k], hi_z[k]}}; }
    constexpr void set_bounds(int k, const AABB<Scalar>& b) noexcept {
        lo_x[k] = b.min.x; lo_y[k] = b.min.y; lo_z[k] = b.min.z;
        hi_x[k] = b.max.x; hi_y[k] = b.max.y; hi_z[k] = b.max.z;
    }
    /// Union of the non-empty slots' boxes.
    constexpr AABB<Scalar> bounds() const noexcept {
        AABB<Scalar> b;
        for (int k = 0; k < W; ++k)
            if (!empty_slot(k)) b.extend(bounds(k));
        return b;
    }
};

static_assert(sizeof(WideNode<>) == 128, "the default wide node is 128 bytes");
static_assert(sizeof(WideNode<float, std::uint32_t, 8>) == 256, "the 8-wide node is 256 bytes");

/// A 4-wide BVH (see the file comment). Made by `make_wide` from a binary `Bvh`.
template <class Scalar = float, class Index = std::uint32_t, class PrimPolicy = prim::indexed, int W = 4>
struct WideBvh {
    using node_type = WideNode<Scalar, Index, W>;
    static constexpr int width = W;
    using scalar_type = Scalar;
    using index_type = Index;
    using prim_policy = PrimPolicy;
    using triangle_type = Triangle<Scalar>;
    static constexpr bool precomputed = std::is_same_v<PrimPolicy, prim::precomputed>;

    /// Root at 0; the children of a node are adjacent (top levels breadth first, subtrees below them depth
    /// first). Empty when there is nothing to trace. Allocated through the scratch cache (scratch.hpp):
    /// a dynamic scene converting every frame reuses the previous frame's block instead of faulting in
    /// and zeroing fresh pages.
    scratch_vector<node_type> nodes;
    /// As Bvh::prim_ids (leaf slot -> user triangle index).
    scratch_vector<index_type> prim_ids;
    /// prim::precomputed only: as Bvh::leaf_triangles.
    scratch_vector<triangle_type> leaf_triangles;
    /// Edges from the root to the deepest wide node (a leaf slot of that node is one level deeper).
    std::uint32_t depth = 0;
    std::size_t primitive_count = 0;   ///< as Bvh::primitive_count
    std::size_t excluded = 0;          ///< as Bvh::excluded

    bool empty() const noexcept { return nodes.empty(); }
    AABB<scalar_type> bounds() const noexcept { return empty() ? AABB<scalar_type>{} : nodes[0].bounds(); }
    std::size_t memory_bytes() const noexcept {
        return nodes.size() * sizeof(node_type) + prim_ids.size() * sizeof(index_type) +
               leaf_triangles.size() * sizeof(triangle_type);
    }
    const triangle_type& triangle(std::span<const triangle_type> tris, std::size_t slot) const noexcept {
        if constexpr (precomputed) return leaf_triangles[slot];
        else return tris[prim_ids[slot]];
    }
};

/// The WideBvh type `make_wide` returns for a binary Bvh type.
template <class B, int W = 4>
using wide_bvh_of = WideBvh<typename B::scalar_type, typename B::index_type, typename B::prim_policy, W>;

namespace detail {

/// Opens binary inner node `b` into up to four children `c` (returns how many): starting from its two
/// children, the inner child of largest surface area is replaced by its two children while fewer than
/// four and some child is inner.
template <int W, class NodeT>
inline int open_wide(std::span<const NodeT> bin, typename NodeT::index_type b, typename NodeT::index_type* c) {
    c[0] = bin[b].left();
    c[1] = bin[b].right();
    int n = 2;
    while (n < W) {
        int best = -1;
        double best_area = -1;
        for (int k = 0; k < n; ++k) {
            const NodeT& ck = bin[c[k]];
            if (ck.is_leaf()) continue;
            const double a = box_area(ck.min, ck.max);
            if (a > best_area) {
                best_area = a;
                best = k;
            }
        }
        if (best < 0) break;
        const NodeT& open = bin[c[best]];
        c[best] = open.left();
        c[n++] = open.right();
    }
    return n;
}

/// Writes the wide node for binary inner node `b` into `w`; calls inner(slot, binary child) for each
/// inner child (the caller sets w.child[slot]).
template <int W, class NodeT, class Inner>
inline void fill_wide(std::span<const NodeT> bin, typename NodeT::index_type b,
                      WideNode<typename NodeT::scalar_type, typename NodeT::index_type, W>& w, Inner&& inner) {
    typename NodeT::index_type c[W];
    const int n = open_wide<W>(bin, b, c);
    w.clear();
    for (int k = 0; k < n; ++k) {
        const NodeT& ck = bin[c[k]];
        w.set_bounds(k, ck.bounds());
        if (ck.is_leaf()) {
            w.child[k] = ck.index;
            w.count[k] = ck.count;
        } else {
            inner(k, c[k]);
        }
    }
}

/// The topology step of the conversion: fills wide.nodes and wide.depth from bvh.nodes. The top of
/// the tree is collapsed serially, breadth first, until 256 subtrees are open; each is then collapsed
/// depth first by one task into its own array, and the arrays are concatenated with their child
/// indices shifted: two parallel steps in all (the cost does not grow with the depth), and the same
/// result on every executor and thread count.
template <int W, class NodeT, class Prim, class Exec>
void collapse_to_wide(const Bvh<NodeT, Prim>& bvh, wide_bvh_of<Bvh<NodeT, Prim>, W>& wide, const Exec& ex) {
    using Index = typename NodeT::index_type;
    using WNode = WideNode<typename NodeT::scalar_type, Index, W>;
    const std::span<const NodeT> bin(bvh.nodes);
    wide.nodes.clear();
    wide.depth = 0;
    if (bin.empty()) return;
    if (bin[0].is_leaf()) {   // a single leaf: one wide node with one slot
        WNode n;
        n.clear();
        n.set_bounds(0, bin[0].bounds());
        n.child[0] = bin[0].index;
        n.count[0] = bin[0].count;
        wide.nodes.push_back(n);
        return;
    }
    struct Pending {
        Index bin;            // binary inner node still to collapse
        Index parent;         // top node whose slot `slot` points to it
        int slot;
        std::uint32_t depth;  // its wide depth
    };
    // Subtrees handed to tasks: a fixed number (not one per worker), so that every executor and
    // thread count produces the same array, and enough to balance a many-core machine.
    constexpr std::size_t target = 256;
    std::vector<WNode> top;
    std::vector<Pending> queue;
    std::size_t head = 0;
    auto expand_top = [&](Index b, std::uint32_t depth) {
        const Index id = Index(top.size());
        top.emplace_back();
        fill_wide<W>(bin, b, top.back(), [&](int slot, Index c) { queue.push_back({c, id, slot, depth + 1}); });
        wide.depth = std::max(wide.depth, depth);
        return id;
    };
    expand_top(Index(0), 0);
    while (head < queue.size() && queue.size() - head < target) {
        const Pending p = queue[head++];
        top[p.parent].child[p.slot] = expand_top(p.bin, p.depth);
    }
    const std::size_t tasks = queue.size() - head;
    std::vector<scratch_vector<WNode>> local(tasks);
    std::vector<std::uint32_t> local_depth(tasks, 0);
    ex.for_tasks(tasks, [&](std::size_t k) {
        const Pending& p = queue[head + k];
        scratch_vector<WNode>& out = local[k];
        // About three binary inner nodes per wide node: a guess that avoids most regrowth.
        out.reserve(bin.size() / (6 * tasks) + 8);
        struct Todo {
            Index bin, at;           // binary node; its wide node's position in `out`
            std::uint32_t depth;
        };
        std::vector<Todo> todo;
        todo.reserve(std::size_t(W) * std::size_t(max_depth));
        out.emplace_back();
        todo.push_back({p.bin, 0, p.depth});
        std::uint32_t deepest = p.depth;
        while (!todo.empty()) {
            const Todo t = todo.back();
            todo.pop_back();
            deepest = std::max(deepest, t.depth);
            WNode w;
            fill_wide<W>(bin, t.bin, w, [&](int slot, Index c) {
                w.child[slot] = Index(out.size());   // local index, shifted when concatenated
                out.emplace_back();
                todo.push_back({c, w.child[slot], t.depth + 1});
            });
            out[t.at] = w;
        }
        local_depth[k] = deepest;
    });
    std::vector<std::size_t> base(tasks);
    std::size_t total = top.size();
    for (std::size_t k = 0; k < tasks; ++k) {
        base[k] = total;
        total += local[k].size();
        const Pending& p = queue[head + k];
        top[p.parent].child[p.slot] = Index(base[k]);
        wide.depth = std::max(wide.depth, local_depth[k]);
    }
    wide.nodes.resize(total);
    std::copy(top.begin(), top.end(), wide.nodes.begin());
    ex.for_tasks(tasks, [&](std::size_t k) {
        const Index shift = Index(base[k]);
        WNode* dst = wide.nodes.data() + base[k];
        for (const WNode& w : local[k]) {
            *dst = w;
            for (int s = 0; s < W; ++s)
                if (dst->count[s] == 0 && !dst->empty_slot(s)) dst->child[s] += shift;
            ++dst;
        }
    });
}


} // namespace detail

/// Converts a binary BVH into a 4-wide one (see the file comment): the same leaves, wide nodes
/// collapsed greedily by surface area. prim_ids and leaf_triangles are copied. O(nodes), parallel
/// over `ex`.
template <int W = 4, class NodeT, class Prim, class Exec = exec::serial>
wide_bvh_of<Bvh<NodeT, Prim>, W> make_wide(const Bvh<NodeT, Prim>& bvh, const Exec& ex = {}) {
    wide_bvh_of<Bvh<NodeT, Prim>, W> w;
    detail::collapse_to_wide<W>(bvh, w, ex);
    w.prim_ids = bvh.prim_ids;
    w.leaf_triangles = bvh.leaf_triangles;
    w.primitive_count = bvh.primitive_count;
    w.excluded = bvh.excluded;
    return w;
}

/// As above, taking over prim_ids and leaf_triangles instead of copying them (the binary tree is
/// left empty).
template <int W = 4, class NodeT, class Prim, class Exec = exec::serial>
wide_bvh_of<Bvh<NodeT, Prim>, W> make_wide(Bvh<NodeT, Prim>&& bvh, const Exec& ex = {}) {
    wide_bvh_of<Bvh<NodeT, Prim>, W> w;
    detail::collapse_to_wide<W>(bvh, w, ex);
    w.prim_ids = std::move(bvh.prim_ids);
    w.leaf_triangles = std::move(bvh.leaf_triangles);
    w.primitive_count = bvh.primitive_count;
    w.excluded = bvh.excluded;
    bvh = Bvh<NodeT, Prim>{};
    return w;
}

/// SAH cost of a wide tree, the binary definition (sah.hpp) with wide nodes as inner nodes:
/// (1 / SA(root)) * (Ct * sum over wide nodes SA(node) + Ci * sum over leaves SA(l) * count(l)),
/// where SA(node) is the area of the union of its children's boxes (one visit tests all of them).
/// The leaf term equals the binary tree's; the inner term sums a subset of its inner nodes.
/// Degenerate roots as in sah_cost(Bvh). O(nodes), parallel over `ex`.
template <class S, class I, class P, int W, class Exec = exec::serial>
double sah_cost(const WideBvh<S, I, P, W>& wide, const SahConfig& cfg = {}, const Exec& ex = {}) {
    if (wide.nodes.empty()) return 0.0;
    const auto& nodes = wide.nodes;
    const detail::SahSums s = ex.reduce(
        std::size_t(0), nodes.size(), detail::SahSums{},
        [&](std::size_t i) {
            const WideNode<S, I, W>& n = nodes[i];
            const AABB<S> b = n.bounds();
            detail::SahSums r;
            r.inner = detail::box_area(b.min, b.max);
            r.inner_n = 1;
            for (int k = 0; k < W; ++k) {
                if (n.empty_slot(k) || !n.is_leaf(k)) continue;
                const AABB<S> c = n.bounds(k);
                r.leaf += detail::box_area(c.min, c.max) * double(n.count[k]);
                r.refs += double(n.count[k]);
            }
            return r;
        },
        [](const detail::SahSums& a, const detail::SahSums& b) { return detail::SahSums::combine(a, b); });
    const AABB<S> rb = nodes[0].bounds();
    const double root = detail::box_area(rb.min, rb.max);
    if (!(root > 0)) return cfg.ct * s.inner_n + cfg.ci * s.refs;
    return (cfg.ct * s.inner + cfg.ci * s.leaf) / root;
}

namespace detail {

/// W box tests at once: a bit mask of the slots hit within [tmin, tmax] and their entry distances
/// (tmax and the distances in the box policy's units, t * p.t_scale, as its test_octant).
/// This portable version runs the box policy's own test_octant on each slot; WideBoxTest is the
/// version traversal uses (SSE, or AVX for 8-wide nodes, for float where available, else this one).
template <class Box, class T>
struct WideBoxTestScalar {
    using prepared = typename Box::template prepared<T>;
    explicit WideBoxTestScalar(const prepared& p) noexcept : p_(p) {}
    template <int Oct, class I, int W>
    DYNBVH_ALWAYS_INLINE unsigned test(const WideNode<T, I, W>& n, T tmax, T* tentry) const noexcept {
        unsigned mask = 0;
        for (int k = 0; k < W; ++k) {
            const Vec3<T> lo{n.lo_x[k], n.lo_y[k], n.lo_z[k]}, hi{n.hi_x[k], n.hi_y[k], n.hi_z[k]};
            mask |= Box::template test_octant<Oct>(p_, lo, hi, tmax, tentry[k]) ? 1u << k : 0u;
        }
        return mask;
    }

private:
    prepared p_;
};

template <class Box, class T, int W = 4>
struct WideBoxTest : WideBoxTestScalar<Box, T> {
    using WideBoxTestScalar<Box, T>::WideBoxTestScalar;
};

#if defined(DYNBVH_WIDE_SSE)
// _mm_max_ps(x, acc) == (x > acc ? x : acc) == max_keep(acc, x), including NaN x and +-0;
// _mm_min_ps(x, acc) == (x < acc ? x : acc) == min_keep(acc, x). The AVX forms behave alike.

/// The SIMD operations the wide box tests use, on four float lanes (SSE).
struct Lanes4 {
    using reg = __m128;
    static constexpr int n = 4;
    static DYNBVH_ALWAYS_INLINE reg from4(__m128 x) noexcept { return x; }
    static DYNBVH_ALWAYS_INLINE reg set1(float x) noexcept { return _mm_set1_ps(x); }
    static DYNBVH_ALWAYS_INLINE reg load(const float* p) noexcept { return _mm_load_ps(p); }
    static DYNBVH_ALWAYS_INLINE void store(float* p, reg a) noexcept { _mm_storeu_ps(p, a); }
    static DYNBVH_ALWAYS_INLINE reg add(reg a, reg b) noexcept { return _mm_add_ps(a, b); }
    static DYNBVH_ALWAYS_INLINE reg sub(reg a, reg b) noexcept { return _mm_sub_ps(a, b); }
    static DYNBVH_ALWAYS_INLINE reg mul(reg a, reg b) noexcept { return _mm_mul_ps(a, b); }
    static DYNBVH_ALWAYS_INLINE reg min(reg a, reg b) noexcept { return _mm_min_ps(a, b); }
    static DYNBVH_ALWAYS_INLINE reg max(reg a, reg b) noexcept { return _mm_max_ps(a, b); }
    static DYNBVH_ALWAYS_INLINE reg abs(reg a) noexcept { return _mm_andnot_ps(_mm_set1_ps(-0.0f), a); }
    /// a * b - c (fused when the compiler targets FMA)
    static DYNBVH_ALWAYS_INLINE reg fmsub(reg a, reg b, reg c) noexcept {
#if defined(__FMA__)
        return _mm_fmsub_ps(a, b, c);
#else
        return _mm_sub_ps(_mm_mul_ps(a, b), c);
#endif
    }
    /// Bit k set when a[k] <= b[k] (false for NaN).
    static DYNBVH_ALWAYS_INLINE unsigned le_mask(reg a, reg b) noexcept { return unsigned(_mm_movemask_ps(_mm_cmple_ps(a, b))); }
};

#if defined(__AVX__)
#define DYNBVH_WIDE_AVX 1
/// The same operations on eight float lanes (AVX), for 8-wide nodes.
struct Lanes8 {
    using reg = __m256;
    static constexpr int n = 8;
    static DYNBVH_ALWAYS_INLINE reg from4(__m128 x) noexcept { return _mm256_insertf128_ps(_mm256_castps128_ps256(x), x, 1); }
    static DYNBVH_ALWAYS_INLINE reg set1(float x) noexcept { return _mm256_set1_ps(x); }
    static DYNBVH_ALWAYS_INLINE reg load(const float* p) noexcept { return _mm256_load_ps(p); }
    static DYNBVH_ALWAYS_INLINE void store(float* p, reg a) noexcept { _mm256_storeu_ps(p, a); }
    static DYNBVH_ALWAYS_INLINE reg add(reg a, reg b) noexcept { return _mm256_add_ps(a, b); }
    static DYNBVH_ALWAYS_INLINE reg sub(reg a, reg b) noexcept { return _mm256_sub_ps(a, b); }
    static DYNBVH_ALWAYS_INLINE reg mul(reg a, reg b) noexcept { return _mm256_mul_ps(a, b); }
    static DYNBVH_ALWAYS_INLINE reg min(reg a, reg b) noexcept { return _mm256_min_ps(a, b); }
    static DYNBVH_ALWAYS_INLINE reg max(reg a, reg b) noexcept { return _mm256_max_ps(a, b); }
    static DYNBVH_ALWAYS_INLINE reg abs(reg a) noexcept { return _mm256_andnot_ps(_mm256_set1_ps(-0.0f), a); }
    static DYNBVH_ALWAYS_INLINE reg fmsub(reg a, reg b, reg c) noexcept {
#if defined(__FMA__)
        return _mm256_fmsub_ps(a, b, c);
#else
        return _mm256_sub_ps(_mm256_mul_ps(a, b), c);
#endif
    }
    static DYNBVH_ALWAYS_INLINE unsigned le_mask(reg a, reg b) noexcept {
        return unsigned(_mm256_movemask_ps(_mm256_cmp_ps(a, b, _CMP_LE_OQ)));
    }
};
/// The widest lanes that divide W: one AVX step per 8-wide node.
template <int W>
using lanes_for = std::conditional_t<W % 8 == 0, Lanes8, Lanes4>;
#else
/// Without AVX, an 8-wide node takes two SSE steps.
template <int W>
using lanes_for = Lanes4;
#endif

/// box::robust on W slots, L::n lanes per step.
template <int W>
struct WideBoxTest<box::robust, float, W> {
    using prepared = box::robust::prepared<float>;
    using L = lanes_for<W>;
    using R = typename L::reg;
    explicit WideBoxTest(const prepared& p) noexcept
        : ox(L::set1(p.org.x)), oy(L::set1(p.org.y)), oz(L::set1(p.org.z)), ix(L::set1(p.inv.x)), iy(L::set1(p.inv.y)),
          iz(L::set1(p.inv.z)), tmin(L::set1(p.tmin)) {}

    /// The same values as from box::robust::prepared (org, inv = 1 / dir correctly rounded, tmin,
    /// octant = direction sign bits, t_scale = 1), computed in a few SSE instructions for the common ray:
    /// traceable and no direction component in (0, FLT_MIN). `ok` is false for any other ray (the
    /// members are then unspecified and the caller uses box::robust::prepared, which handles it).
    /// The per-ray setup is a large part of a primary ray's cost, most of which miss early.
    WideBoxTest(const Ray<float>& r, bool& ok, int& octant) noexcept {
        const __m128 d = _mm_setr_ps(r.dir.x, r.dir.y, r.dir.z, 1.0f);
        const __m128 o = _mm_setr_ps(r.org.x, r.org.y, r.org.z, 0.0f);
        const __m128 sign = _mm_set1_ps(-0.0f), inf = _mm_set1_ps(std::numeric_limits<float>::infinity());
        const __m128 ad = _mm_andnot_ps(sign, d), ao = _mm_andnot_ps(sign, o);
        const int finite = _mm_movemask_ps(_mm_and_ps(_mm_cmplt_ps(ad, inf), _mm_cmplt_ps(ao, inf)));  // false for NaN
        const int tiny = _mm_movemask_ps(_mm_and_ps(_mm_cmpgt_ps(ad, _mm_setzero_ps()),
                                                    _mm_cmplt_ps(ad, _mm_set1_ps(std::numeric_limits<float>::min()))));
        const int nonzero = _mm_movemask_ps(_mm_cmpneq_ps(d, _mm_setzero_ps())) & 7;
        ok = finite == 15 && tiny == 0 && nonzero != 0 && r.tmin <= r.tmax;
        const __m128 inv = _mm_div_ps(_mm_set1_ps(1.0f), d);
        octant = _mm_movemask_ps(d) & 7;
        ox = L::from4(_mm_shuffle_ps(o, o, 0x00));
        oy = L::from4(_mm_shuffle_ps(o, o, 0x55));
        oz = L::from4(_mm_shuffle_ps(o, o, 0xaa));
        ix = L::from4(_mm_shuffle_ps(inv, inv, 0x00));
        iy = L::from4(_mm_shuffle_ps(inv, inv, 0x55));
        iz = L::from4(_mm_shuffle_ps(inv, inv, 0xaa));
        tmin = L::set1(r.tmin);
    }
    template <int Oct, class I>
    DYNBVH_ALWAYS_INLINE unsigned test(const WideNode<float, I, W>& n, float tmax, float* tentry) const noexcept {
        unsigned mask = 0;
        for (int h = 0; h < W; h += L::n) {
            const R x0 = L::mul(L::sub(L::load((Oct & 1 ? n.hi_x : n.lo_x) + h), ox), ix);
            const R x1 = L::mul(L::sub(L::load((Oct & 1 ? n.lo_x : n.hi_x) + h), ox), ix);
            const R y0 = L::mul(L::sub(L::load((Oct & 2 ? n.hi_y : n.lo_y) + h), oy), iy);
            const R y1 = L::mul(L::sub(L::load((Oct & 2 ? n.lo_y : n.hi_y) + h), oy), iy);
            const R z0 = L::mul(L::sub(L::load((Oct & 4 ? n.hi_z : n.lo_z) + h), oz), iz);
            const R z1 = L::mul(L::sub(L::load((Oct & 4 ? n.lo_z : n.hi_z) + h), oz), iz);
            const R tn = L::max(z0, L::max(y0, L::max(x0, tmin)));
            R tf = L::min(z1, L::min(y1, L::min(x1, L::set1(tmax))));
            tf = L::add(tf, L::mul(L::set1(2.0f * rounding_gamma<float>(3)), L::abs(tf)));   // box::robust::widen
            L::store(tentry + h, tn);
            mask |= L::le_mask(tn, tf) << h;
        }
        return mask;
    }

private:
    R ox, oy, oz, ix, iy, iz, tmin;
};

/// box::fast on W slots, L::n lanes per step.
template <int W>
struct WideBoxTest<box::fast, float, W> {
    using prepared = box::fast::prepared<float>;
    using L = lanes_for<W>;
    using R = typename L::reg;
    explicit WideBoxTest(const prepared& p) noexcept
        : ix(L::set1(p.inv.x)), iy(L::set1(p.inv.y)), iz(L::set1(p.inv.z)), oix(L::set1(p.org_inv.x)),
          oiy(L::set1(p.org_inv.y)), oiz(L::set1(p.org_inv.z)), tmin(L::set1(p.tmin)) {}
    template <int Oct, class I>
    DYNBVH_ALWAYS_INLINE unsigned test(const WideNode<float, I, W>& n, float tmax, float* tentry) const noexcept {
        unsigned mask = 0;
        for (int h = 0; h < W; h += L::n) {
            const R x0 = L::fmsub(L::load((Oct & 1 ? n.hi_x : n.lo_x) + h), ix, oix);
            const R x1 = L::fmsub(L::load((Oct & 1 ? n.lo_x : n.hi_x) + h), ix, oix);
            const R y0 = L::fmsub(L::load((Oct & 2 ? n.hi_y : n.lo_y) + h), iy, oiy);
            const R y1 = L::fmsub(L::load((Oct & 2 ? n.lo_y : n.hi_y) + h), iy, oiy);
            const R z0 = L::fmsub(L::load((Oct & 4 ? n.hi_z : n.lo_z) + h), iz, oiz);
            const R z1 = L::fmsub(L::load((Oct & 4 ? n.lo_z : n.hi_z) + h), iz, oiz);
            const R tn = L::max(z0, L::max(y0, L::max(x0, tmin)));
            const R tf = L::min(z1, L::min(y1, L::min(x1, L::set1(tmax))));
            L::store(tentry + h, tn);
            mask |= L::le_mask(tn, tf) << h;
        }
        return mask;
    }

private:
    R ix, iy, iz, oix, oiy, oiz, tmin;
};
#endif  // DYNBVH_WIDE_SSE

template <class Index, class T>
struct WideStackEntry {
    Index child;   ///< node index (count 0) or first prim_ids slot (count > 0)
    Index count;
    T tentry;
};

/// The wide traversal loop for one direction octant; same contract as traverse_octant (traverse.hpp).
/// Box distances are in box::robust's units (t * t_scale). The triangle test's per-ray setup is
/// done when the first leaf is reached: most primary rays of an open scene never reach one.
template <class Policy, bool AnyHit, int Oct, class S, class I, class P, int W>
bool wide_traverse_octant(const WideBvh<S, I, P, W>& bvh, std::span<const Triangle<S>> tris, const Ray<S>& ray,
                          const S t_scale,
                          const WideBoxTest<typename Policy::box_test, S, W> wb, Hit<S>& hit,
                          WideStackEntry<I, S>* const stack, const std::size_t cap) {
    using Box = typename Policy::box_test;
    using Tri = typename Policy::triangle_test;
    using Entry = WideStackEntry<I, S>;
    using WB = WideBvh<S, I, P, W>;

    const WideNode<S, I, W>* const nodes = bvh.nodes.data();
    const I* const ids = bvh.prim_ids.data();
    const Triangle<S>* const leaf_tris = WB::precomputed ? bvh.leaf_triangles.data() : tris.data();
    // The triangle test's setup, made at the first leaf. (Not std::optional: GCC zero-fills its storage
    // with `rep stos` on every ray, a tenth of a primary ray's cost when most rays reach no leaf.)
    using TriPrepared = typename Tri::template prepared<S>;
    static_assert(std::is_trivially_destructible_v<TriPrepared>);
    union LazyPrepared {
        LazyPrepared() noexcept {}
        TriPrepared value;
    } pt;
    bool have_pt = false;

    S tmax = ray.tmax;
    S tbox = tmax * t_scale;   // tmax in box units
    std::size_t sp = 0;
    std::size_t best_slot = ~std::size_t(0);
    I cur = 0, cur_count = 0;
    for (;;) {
        if (cur_count == 0) {
            const WideNode<S, I, W>& n = nodes[cur];
            alignas(32) S t[W];
            unsigned mask = wb.template test<Oct>(n, tbox, t);
            if (mask != 0) {
                const int a = std::countr_zero(mask);
                mask &= mask - 1;
                if (mask == 0) {   // one child hit: go there
                    cur = n.child[a];
                    cur_count = n.count[a];
                    continue;
                }
                const int b = std::countr_zero(mask);
                mask &= mask - 1;
                if (mask == 0) {   // two: the nearer now, the farther on the stack
                    if (sp + 1 > cap) [[unlikely]] return false;
                    const bool swap = t[b] < t[a];
                    const int near = swap ? b : a, far = swap ? a : b;
                    stack[sp++] = Entry{n.child[far], n.count[far], t[far]};
                    cur = n.child[near];
                    cur_count = n.count[near];
                    continue;
                }
                // Three or more: sort by entry distance, push all but the nearest, farthest first.
                if (sp + (W - 1) > cap) [[unlikely]] return false;
                int order[W] = {a, b};
                int m = 2;
                for (; mask != 0; mask &= mask - 1) order[m++] = std::countr_zero(mask);
                for (int i = 1; i < m; ++i)
                    for (int j = i; j > 0 && t[order[j]] < t[order[j - 1]]; --j) std::swap(order[j], order[j - 1]);
                for (int i = m - 1; i > 0; --i) stack[sp++] = Entry{n.child[order[i]], n.count[order[i]], t[order[i]]};
                cur = n.child[order[0]];
                cur_count = n.count[order[0]];
                continue;
            }
        } else {
            if (!have_pt) [[unlikely]] {
                ::new (static_cast<void*>(&pt.value)) TriPrepared(ray);
                have_pt = true;
            }
            if (test_leaf<Tri, AnyHit, WB::precomputed>(pt.value, leaf_tris, ids, cur, std::size_t(cur) + cur_count, t_scale, tmax,
                                                        tbox, best_slot, hit))
                return true;
        }
        // Pop the next subtree that can still hold a closer hit.
        for (;;) {
            if (sp == 0) {
                if (best_slot != ~std::size_t(0)) hit.prim = static_cast<std::uint32_t>(ids[best_slot]);
                return true;
            }
            const Entry e = stack[--sp];
            if (Box::before(e.tentry, tbox)) {
                cur = e.child;
                cur_count = e.count;
                break;
            }
        }
    }
}

/// Stack and octant dispatch around wide_traverse_octant for a prepared ray.
template <class Policy, bool AnyHit, class S, class I, class P, int W>
Hit<S> wide_run(const WideBvh<S, I, P, W>& bvh, std::span<const Triangle<S>> tris, const Ray<S>& ray,
                const WideBoxTest<typename Policy::box_test, S, W>& wb, S t_scale, int octant) {
    using Entry = WideStackEntry<I, S>;
    auto run = [&](Entry* stack, std::size_t cap, Hit<S>& hit) {
        return dispatch_octant(octant, [&](auto oct) {
            return wide_traverse_octant<Policy, AnyHit, decltype(oct)::value>(bvh, tris, ray, t_scale, wb, hit, stack, cap);
        });
    };
    // At most W - 1 entries per wide level: wide depth < binary depth <= max_depth.
    constexpr std::size_t fixed_cap = std::size_t(W - 1) * std::size_t(max_depth);
    if (bvh.depth < max_depth) {
        Entry stack[fixed_cap];
        Hit<S> hit;
        if (run(stack, fixed_cap, hit)) [[likely]] return hit;
    }
    // Each node's children are pushed at most once: W - 1 entries per node bound any traversal.
    std::vector<Entry> heap(std::size_t(W - 1) * (bvh.nodes.size() + 1));
    Hit<S> hit;
    run(heap.data(), heap.size(), hit);
    return hit;
}

template <class Policy, bool AnyHit, class S, class I, class P, int W>
Hit<S> wide_traverse(const WideBvh<S, I, P, W>& bvh, std::span<const Triangle<S>> tris, const Ray<S>& ray) {
    using Box = typename Policy::box_test;
    if (bvh.nodes.empty()) return {};
#if defined(DYNBVH_WIDE_SSE)
    if constexpr (std::is_same_v<Box, box::robust> && std::is_same_v<S, float>) {
        bool ok;
        int octant;
        const WideBoxTest<Box, S, W> wb(ray, ok, octant);
        if (ok) [[likely]] return wide_run<Policy, AnyHit>(bvh, tris, ray, wb, S(1), octant);
    }
#endif
    // No separate traceable() check: the prepared ray of a ray that is not traceable has a NaN tmin,
    // so every box test misses and no leaf is reached (tests cover it).
    const typename Box::template prepared<S> pb(ray);
    return wide_run<Policy, AnyHit>(bvh, tris, ray, WideBoxTest<Box, S, W>(pb), pb.t_scale, pb.octant);
}

} // namespace detail

/// Closest hit in a wide BVH; same contract as intersect(Bvh, ...) in traverse.hpp.
template <class Policy = trace::robust, class S, class I, class P, int W>
Hit<S> intersect(const WideBvh<S, I, P, W>& bvh, std::type_identity_t<std::span<const Triangle<S>>> tris,
                 const std::type_identity_t<Ray<S>>& ray) {
    detail::check_triangles(bvh, tris.size(), "intersect", !WideBvh<S, I, P, W>::precomputed);
    return detail::wide_traverse<Policy, false>(bvh, tris, ray);
}

/// Any hit in a wide BVH; same contract as occluded(Bvh, ...) in traverse.hpp.
template <class Policy = trace::robust, class S, class I, class P, int W>
bool occluded(const WideBvh<S, I, P, W>& bvh, std::type_identity_t<std::span<const Triangle<S>>> tris,
              const std::type_identity_t<Ray<S>>& ray) {
    detail::check_triangles(bvh, tris.size(), "occluded", !WideBvh<S, I, P, W>::precomputed);
    return static_cast<bool>(detail::wide_traverse<Policy, true>(bvh, tris, ray));
}

} // namespace dynbvh
