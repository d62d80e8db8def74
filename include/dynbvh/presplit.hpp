// SPDX-License-Identifier: MIT
/// @file presplit.hpp
/// Triangle presplitting: Karras & Aila 2013, "Fast Parallel Construction of High-Quality
/// Bounding Volume Hierarchies" (HPG), section 5. Before a BVH is built, triangles whose boxes fit
/// them badly (long, thin, diagonal) are cut into fragments with tight boxes, so the builder sees
/// small, well-fitting references. A leaf that ends up with two fragments of one triangle tests it
/// once (detail::emit_bvh in detail/emit.hpp removes the duplicate).
///
/// The budget is s_max = floor(beta * m) extra fragments for m triangles. Each triangle t gets a
/// priority p_t = (X^i_t * (A_aabb(t) - A_ideal(t)))^Y with the paper's X = 2, Y = 1/3, where
///  - A_aabb is the surface area of the triangle's box;
///  - A_ideal is the least box area splitting could ever reach: the box area of infinitely many
///    infinitely small pieces, 2 * (|A_yz| + |A_zx| + |A_xy|) with A_.. the projected triangle areas;
///  - i_t (0..62) is the importance of the most important plane of the scene's Morton grid
///    (2^21 cells per axis over the scene bounds) strictly inside the box: the index of the highest
///    bit in which the 63-bit Morton codes of the cells holding the box's corners differ (a max face
///    lying exactly on a plane counts in the cell below). The root-level planes (scene midplanes)
///    are the most important, as they are the ones LBVH/PLOC split at first. A box inside one cell
///    has no plane and priority 0.
/// Triangle t gets s_t = floor(D * p_t) splits with D the largest scale such that sum s_t <= s_max,
/// and the few splits rounding leaves over go to the triangles that would get their next split first
/// as D grows, so exactly s_max splits are made whenever any triangle has a positive priority.
/// A triangle with s splits is cut recursively: at the most important grid plane crossing the current
/// fragment's box (falling back to the middle of its longest axis), the fragment polygon is clipped
/// (Sutherland-Hodgman) so both halves get tight boxes, and the s - 1 remaining splits are shared as
/// s_a = floor((s - 1) * w_a / (w_a + w_b) + 1/2), s_b = s - 1 - s_a, w = longest axis of each half's
/// box (the paper's weights). A box too small to cut (a point) is repeated instead, keeping the count.
#pragma once

#include <algorithm>
#include <bit>
#include <cmath>
#include <cstdint>
#include <limits>
#include <span>
#include <stdexcept>
#include <string>
#include <vector>

#include "aabb.hpp"
#include "cost.hpp"
#include "detail/polygon.hpp"
#include "executor.hpp"
#include "detail/morton.hpp"
#include "detail/references.hpp"
#include "detail/scratch.hpp"
#include "triangle.hpp"

namespace dynbvh::presplit {

/// Presplitting knobs. Designated-initialiser friendly: `{.beta = 0.1f}`.
struct Config {
    /// Split budget as a fraction of the triangle count: floor(beta * m) extra fragments in all
    /// (the paper's beta; the study used 0.05). 0 disables splitting. Must be finite and >= 0;
    /// values above 1 are allowed (more fragments than triangles).
    float beta = 0.05f;
};

/// Extra fragments `split` makes for `m` references when at least one triangle can be split:
/// floor(beta * m). Throws std::invalid_argument for a negative or non-finite beta.
inline std::size_t budget(std::size_t m, const Config& cfg) {
    if (!(cfg.beta >= 0.0f) || !std::isfinite(cfg.beta))
        throw std::invalid_argument("dynbvh::presplit: beta must be finite and >= 0, got " + std::to_string(cfg.beta));
    return static_cast<std::size_t>(std::floor(static_cast<double>(cfg.beta) * static_cast<double>(m)));
}

namespace detail {

using dynbvh::detail::Polygon;
using dynbvh::detail::split_polygon;

/// A_ideal of a planar polygon: 2 * (|yz| + |zx| + |xy| projected areas), in double.
template <class T>
double ideal_area(const Polygon<T>& poly) noexcept {
    if (poly.n < 3) return 0.0;
    double sx = 0, sy = 0, sz = 0;
    const double ox = poly.x[0], oy = poly.y[0], oz = poly.z[0];
    for (int k = 1; k + 1 < poly.n; ++k) {
        const double ax = poly.x[k] - ox, ay = poly.y[k] - oy, az = poly.z[k] - oz;
        const double bx = poly.x[k + 1] - ox, by = poly.y[k + 1] - oy, bz = poly.z[k + 1] - oz;
        sx += ay * bz - az * by;
        sy += az * bx - ax * bz;
        sz += ax * by - ay * bx;
    }
    // Each sum is twice a projected area; the box area counts every face twice: 2 * 0.5 * |s|.
    return std::abs(sx) + std::abs(sy) + std::abs(sz);
}

/// Grid cells holding a box's lower and upper face on axis a. An upper face lying exactly on a grid
/// plane counts in the cell below it, so the planes strictly inside the box are the ones between
/// `lo` and `hi`. Computed in double so that fine levels stay exact for float scenes.
template <class T>
void face_cells(const AABB<T>& box, const morton::Quantizer<T>& q, std::size_t a, std::uint64_t& lo, std::uint64_t& hi) noexcept {
    const double top = static_cast<double>(q.cells) - 1.0;
    const double s = static_cast<double>(q.scale[a]), o = static_cast<double>(q.origin[a]);
    const double c0 = (static_cast<double>(box.min[a]) - o) * s, c1 = (static_cast<double>(box.max[a]) - o) * s;
    // Truncation is floor here: negative, zero and NaN values are caught first.
    lo = !(c0 > 0.0) ? 0 : c0 >= top ? static_cast<std::uint64_t>(top) : static_cast<std::uint64_t>(c0);
    if (!(c1 > 0.0)) hi = 0;
    else if (c1 > top) hi = static_cast<std::uint64_t>(top);
    else {
        hi = static_cast<std::uint64_t>(c1);                       // floor(c1)
        if (hi > 0 && static_cast<double>(hi) == c1) --hi;         // on a plane: the cell below
    }
    if (hi < lo) hi = lo;
}

/// Rank of the most important grid plane strictly inside the box on axis a, in Morton bit order
/// (3 * level + 2 - a, x highest as in morton.hpp), or -1 when there is none; `level` is the plane's.
template <class T>
int plane_rank(const AABB<T>& box, const morton::Quantizer<T>& q, int a, int& level, std::uint64_t& cell) noexcept {
    std::uint64_t lo, hi;
    face_cells(box, q, std::size_t(a), lo, hi);
    const std::uint64_t d = lo ^ hi;
    if (d == 0) return -1;
    level = static_cast<int>(std::bit_width(d)) - 1;
    cell = (hi >> level) << level;   // lo < cell <= hi: the one plane of that level inside
    return 3 * level + (2 - a);
}

/// i_t: the highest bit in which the 63-bit Morton codes of the box's corners differ (0..62), i.e.
/// the rank of the most important grid plane crossing the box; -1 when the box sits in one cell.
template <class T>
int importance(const AABB<T>& box, const morton::Quantizer<T>& q) noexcept {
    int best = -1, level = 0;
    std::uint64_t cell = 0;
    for (int a = 0; a < 3; ++a) best = std::max(best, plane_rank(box, q, a, level, cell));
    return best;
}

/// Where to cut `box`: the most important grid plane strictly inside it, else the middle of the
/// longest axis that can still be halved. False when the box is too small to cut at all.
template <class T>
bool choose_plane(const AABB<T>& box, const morton::Quantizer<T>& q, int& axis, T& pos) noexcept {
    int best = -1, best_rank = -1;
    T best_pos{};
    for (std::size_t a = 0; a < 3; ++a) {
        int level = 0;
        std::uint64_t cell = 0;
        const int rank = plane_rank(box, q, int(a), level, cell);
        if (rank <= best_rank) continue;
        const T at = static_cast<T>(static_cast<double>(q.origin[a]) + static_cast<double>(cell) / static_cast<double>(q.scale[a]));
        if (!(box.min[a] < at && at < box.max[a])) continue;   // rounded onto a face
        best = int(a);
        best_rank = rank;
        best_pos = at;
    }
    if (best >= 0) {
        axis = best;
        pos = best_pos;
        return true;
    }
    const Vec3<T> d = box.diagonal();
    std::size_t order[3] = {0, 1, 2};
    std::sort(order, order + 3, [&](std::size_t x, std::size_t y) { return d[x] > d[y] || (d[x] == d[y] && x < y); });
    for (std::size_t a : order) {
        const T mid = box.min[a] + (box.max[a] - box.min[a]) * T(0.5);
        if (box.min[a] < mid && mid < box.max[a]) {
            axis = int(a);
            pos = mid;
            return true;
        }
    }
    return false;
}

/// The corners' box, grown on every axis where a crossing point was rounded by 16 unit roundoffs of
/// the largest coordinate magnitude there. Crossing points carry a few roundings per cut, so the exact
/// part of the triangle inside a cut can stick out of its corners' box by that much; without the
/// margin a ray that hits the triangle next to a split plane can miss every fragment box
/// (tests/test_robust_geometry.cpp, scenes far from the origin). Callers intersect the result with the
/// cut, so it never leaves the parent box; exact crossings (hand-made cases) keep boxes tight.
template <class T>
AABB<T> conservative_bounds(const Polygon<T>& poly) noexcept {
    AABB<T> b = poly.bounds();
    constexpr T k = T(8) * std::numeric_limits<T>::epsilon();
    for (std::size_t a = 0; a < 3; ++a) {
        if (!poly.rounded[a]) continue;
        const T m = k * std::max(std::abs(b.min[a]), std::abs(b.max[a]));
        b.min[a] -= m;
        b.max[a] += m;
    }
    return b;
}

/// The triangle restricted to `box` (the reference's box; usually the triangle's own box, in which
/// case nothing is clipped), and its tight box inside `box`.
template <class T>
void initial_fragment(const Triangle<T>& tri, const AABB<T>& box, Polygon<T>& poly, AABB<T>& tight) noexcept {
    poly.n = 0;
    poly.overflow = false;
    poly.rounded[0] = poly.rounded[1] = poly.rounded[2] = false;
    poly.push(tri.p0);
    poly.push(tri.p1);
    poly.push(tri.p2);
    poly.close();
    if (!box.contains(tri.bounds())) {
        Polygon<T> lo, hi;
        for (int a = 0; a < 3; ++a) {
            split_polygon(poly, a, box.min[std::size_t(a)], lo, hi);
            poly = hi;
            split_polygon(poly, a, box.max[std::size_t(a)], lo, hi);
            poly = lo;
        }
    }
    tight = intersection(conservative_bounds(poly), box);
    if (poly.n == 0 || poly.overflow || tight.is_empty()) tight = box;
}

/// p_t = (2^i * (A_aabb - A_ideal))^(1/3) for a fragment box and its ideal area (0 when the box
/// cannot or need not be split).
template <class T>
double priority(const AABB<T>& box, double ideal, const morton::Quantizer<T>& q) noexcept {
    const int i = importance(box, q);
    if (i < 0) return 0.0;
    const double surplus = dynbvh::detail::area(box) - ideal;
    if (!(surplus > 0.0) || !std::isfinite(surplus)) return 0.0;
    return std::cbrt(surplus * static_cast<double>(std::uint64_t(1) << i));   // X = 2, Y = 1/3
}

/// p_t of the part of `tri` inside its reference box `ref`.
template <class T>
double priority(const Triangle<T>& tri, const AABB<T>& ref, const morton::Quantizer<T>& q) noexcept {
    const AABB<T> tb = tri.bounds();
    if (!ref.contains(tb)) {   // a reference already cut to part of its triangle
        Polygon<T> poly;
        AABB<T> box;
        initial_fragment(tri, ref, poly, box);
        return priority(box, ideal_area(poly), q);
    }
    const double ax = double(tri.p1.x) - double(tri.p0.x), ay = double(tri.p1.y) - double(tri.p0.y),
                 az = double(tri.p1.z) - double(tri.p0.z);
    const double bx = double(tri.p2.x) - double(tri.p0.x), by = double(tri.p2.y) - double(tri.p0.y),
                 bz = double(tri.p2.z) - double(tri.p0.z);
    return priority(tb, std::abs(ay * bz - az * by) + std::abs(az * bx - ax * bz) + std::abs(ax * by - ay * bx), q);
}

/// Indices i in [0, n) with pred(i), in increasing order. O(n), parallel.
template <class Pred, class Exec>
scratch_vector<std::uint32_t> select(std::size_t n, Pred&& pred, const Exec& ex) {
    scratch_vector<std::uint32_t> flag(n), offset(n);
    ex.for_each(0, n, [&](std::size_t i) { flag[i] = pred(i) ? 1u : 0u; });
    const std::uint32_t total =
        ex.exclusive_scan(std::span<const std::uint32_t>(flag), std::span<std::uint32_t>(offset));
    scratch_vector<std::uint32_t> out(total);
    ex.for_each(0, n, [&](std::size_t i) {
        if (flag[i]) out[offset[i]] = static_cast<std::uint32_t>(i);
    });
    return out;
}

/// Splits per reference: s_t = floor(D * p_t) with the largest feasible D found by bisection, then the
/// leftover handed to the next split points beyond D. The result depends only on `prio` and `s_max`,
/// never on the executor (every sum is of integers, the bracket only changes how fast it converges).
template <class Exec>
scratch_vector<std::uint32_t> allocate(std::span<const double> prio, std::size_t s_max, const Exec& ex) {
    const std::size_t m = prio.size();
    scratch_vector<std::uint32_t> count(m);
    ex.for_each(0, m, [&](std::size_t i) { count[i] = 0; });
    if (s_max == 0 || m == 0) return count;

    struct Stats {
        double max = 0, sum = 0;
        std::size_t positive = 0;
    };
    const Stats st = ex.reduce(
        std::size_t(0), m, Stats{},
        [&](std::size_t i) { return Stats{prio[i], prio[i], prio[i] > 0 ? std::size_t(1) : std::size_t(0)}; },
        [](const Stats& a, const Stats& b) { return Stats{std::max(a.max, b.max), a.sum + b.sum, a.positive + b.positive}; });
    if (st.positive == 0) return count;

    const auto s_target = static_cast<std::uint64_t>(s_max);
    // Bracket sizes below which a pass over the candidates runs on the calling thread (a parallel
    // pass costs more than it saves there).
    constexpr std::size_t parallel_min = std::size_t(1) << 14;
    scratch_vector<std::uint32_t> cand;   // references whose split count still depends on D
    scratch_vector<double> cp;            // their priorities
    std::uint64_t settled = 0;         // splits of the references no longer in cand (count[] written)
    auto total = [&](double d) {
        const auto of = [&](std::size_t k) { return static_cast<std::uint64_t>(d * cp[k]); };   // floor: d * p >= 0
        if (cp.size() < parallel_min) {
            std::uint64_t t = settled;
            for (std::size_t k = 0; k < cp.size(); ++k) t += of(k);
            return t;
        }
        return settled + ex.reduce(std::size_t(0), cp.size(), std::uint64_t(0), of, [](std::uint64_t a, std::uint64_t b) { return a + b; });
    };
    // Only references with floor(hi * p) >= 1 can get a split for any D <= hi.
    auto compact = [&](double hi) {
        cand = select(m, [&](std::size_t i) { return prio[i] > 0 && hi * prio[i] >= 1.0; }, ex);
        cp.resize(cand.size());
        ex.for_each(0, cand.size(), [&](std::size_t k) { cp[k] = prio[cand[k]]; });
    };
    // Once the bracket is (lo, hi], a reference with floor(lo p) == floor(hi p) has its final count: it
    // is written and leaves the candidates, so each bisection step reads only the references whose
    // count the step can still change (the set shrinks with the bracket). Same result as summing all.
    auto narrow = [&](double lo, double hi) {
        const auto fixed = [&](std::size_t k) { return static_cast<std::uint64_t>(lo * cp[k]) == static_cast<std::uint64_t>(hi * cp[k]); };
        std::size_t w = 0;
        if (cp.size() < parallel_min) {
            for (std::size_t k = 0; k < cp.size(); ++k) {
                if (fixed(k)) {
                    const auto c = static_cast<std::uint32_t>(lo * cp[k]);
                    count[cand[k]] = c;
                    settled += c;
                } else {
                    cand[w] = cand[k];
                    cp[w++] = cp[k];
                }
            }
        } else {
            settled += ex.reduce(std::size_t(0), cp.size(), std::uint64_t(0), [&](std::size_t k) -> std::uint64_t {
                if (!fixed(k)) return 0;
                const auto c = static_cast<std::uint32_t>(lo * cp[k]);
                count[cand[k]] = c;
                return c;
            }, [](std::uint64_t a, std::uint64_t b) { return a + b; });
            const scratch_vector<std::uint32_t> keep = select(cp.size(), [&](std::size_t k) { return !fixed(k); }, ex);
            scratch_vector<std::uint32_t> kc(keep.size());
            scratch_vector<double> kp(keep.size());
            ex.for_each(0, keep.size(), [&](std::size_t j) {
                kc[j] = cand[keep[j]];
                kp[j] = cp[keep[j]];
            });
            w = keep.size();
            cand = std::move(kc);
            cp = std::move(kp);
        }
        cand.resize(w);
        cp.resize(w);
    };

    // Infeasible upper bounds: the top priority alone gets s_max + 1 splits; and
    // sum floor(D p) > D * sum p - positive = s_max + 1 at D = (s_max + positive + 1) / sum p.
    double hi = std::min((static_cast<double>(s_max) + 1.0) / st.max,
                         (static_cast<double>(s_max) + static_cast<double>(st.positive) + 1.0) / st.sum);
    compact(hi);
    while (total(hi) <= s_target) {
        hi *= 2.0;
        compact(hi);
    }
    // Feasible lower bound: sum floor(D p) <= D * sum p.
    double lo = std::min(hi, static_cast<double>(s_max) / st.sum) * (1.0 - 1e-9);
    if (!(lo > 0.0) || total(lo) > s_target) lo = 0.0;
    std::uint64_t lo_total = lo > 0.0 ? total(lo) : 0;
    narrow(lo, hi);
    for (int it = 0; it < 256 && lo_total != s_target && !cand.empty(); ++it) {
        const double mid = lo + (hi - lo) * 0.5;
        if (!(mid > lo && mid < hi)) break;   // adjacent doubles: D found
        const std::uint64_t c = total(mid);
        if (c <= s_target) {
            lo = mid;
            lo_total = c;
        } else {
            hi = mid;
        }
        narrow(lo, hi);
    }

    for (std::size_t k = 0; k < cand.size(); ++k)
        count[cand[k]] = static_cast<std::uint32_t>(lo * cp[k]);
    std::uint64_t left = s_target - lo_total;
    if (left > 0) {
        // Ties at the jump past D (and only those, once D has converged): give the leftover to the
        // split points (s_t + j) / p_t in (lo, hi] in increasing order, index breaking ties.
        struct Unit {
            double at;
            std::uint32_t ref;
        };
        std::vector<Unit> units;
        for (std::size_t k = 0; k < cand.size(); ++k) {
            const auto base = static_cast<std::uint64_t>(lo * cp[k]);
            const auto top = static_cast<std::uint64_t>(hi * cp[k]);
            for (std::uint64_t j = base + 1; j <= top; ++j) units.push_back({static_cast<double>(j) / cp[k], cand[k]});
        }
        const auto cmp = [](const Unit& a, const Unit& b) { return a.at < b.at || (a.at == b.at && a.ref < b.ref); };
        const std::size_t take = static_cast<std::size_t>(std::min<std::uint64_t>(left, units.size()));
        std::partial_sort(units.begin(), units.begin() + static_cast<std::ptrdiff_t>(take), units.end(), cmp);
        for (std::size_t u = 0; u < take; ++u) ++count[units[u].ref];
        left -= take;
        // Unreachable in exact arithmetic (total(hi) > s_max); keeps the budget exact regardless.
        for (std::size_t k = 0; left > 0 && !cand.empty(); k = (k + 1) % cand.size(), --left) ++count[cand[k]];
    }
    return count;
}

} // namespace detail

/// Splits the references' triangles into fragments (see the file comment). Every reference becomes
/// 1 + s_t fragments, stored contiguously in input order; each fragment's `prim` is its triangle's.
/// Fragment boxes are tight boxes of the clipped triangle, lie inside the reference's box, and together
/// cover the whole triangle. primitive_count and excluded are copied; bounds are recomputed.
/// `tris` is the user's triangles (a span or a MeshView) that `refs.prim` indexes. beta = 0 returns `refs` unchanged.
/// O(m + s_max) work (plus a bisection over the few candidates), parallel; the output does not
/// depend on the executor. Throws std::invalid_argument for a bad beta and std::length_error
/// when the fragments would exceed 2^31 - 1 references.
template <class T, dynbvh::detail::triangle_source Source, class Exec>
References<T> split(const References<T>& refs, Source tris, const Config& cfg, const Exec& ex) {
    const std::size_t m = refs.size();
    const std::size_t s_max = budget(m, cfg);
    if (s_max == 0) return refs;
    if (m + s_max >= (std::size_t(1) << 31))
        throw std::length_error("dynbvh::presplit: " + std::to_string(m) + " references + " + std::to_string(s_max) +
                                " splits exceed the limit of 2^31 - 1 references");

    // The grid LBVH and PLOC split along first: Morton planes over the scene bounds.
    const morton::Quantizer<T> q(refs.bounds, morton::grid_bits<std::uint64_t>);

    scratch_vector<double> prio(m);
    ex.for_each(0, m, [&](std::size_t i) { prio[i] = detail::priority(tris[refs.prim[i]], refs.box[i], q); });
    const scratch_vector<std::uint32_t> count = detail::allocate(std::span<const double>(prio), s_max, ex);

    scratch_vector<std::size_t> offset(m);
    ex.for_each(0, m, [&](std::size_t i) { offset[i] = std::size_t(count[i]) + 1; });
    const std::size_t total = ex.exclusive_scan(std::span<const std::size_t>(offset), std::span<std::size_t>(offset));

    References<T> out;
    out.box.resize(total);
    out.prim.resize(total);
    out.primitive_count = refs.primitive_count;
    out.excluded = refs.excluded;
    out.repeats = refs.repeats || total != m;

    struct Task {
        detail::Polygon<T> poly;
        AABB<T> box;
        std::uint32_t splits;
    };
    ex.for_blocks(0, m, [&](std::size_t begin, std::size_t end) {
        std::vector<Task> stack;
        for (std::size_t i = begin; i < end; ++i) {
            std::size_t slot = offset[i];
            const std::uint32_t prim = refs.prim[i];
            if (count[i] == 0) {
                out.box[slot] = refs.box[i];
                out.prim[slot] = prim;
                continue;
            }
            stack.clear();
            stack.push_back({});
            detail::initial_fragment(tris[prim], refs.box[i], stack.back().poly, stack.back().box);
            stack.back().splits = count[i];
            while (!stack.empty()) {
                const Task t = stack.back();
                stack.pop_back();
                int axis = 0;
                T pos{};
                if (t.splits == 0 || !detail::choose_plane(t.box, q, axis, pos)) {
                    // Done, or a box too small to cut: keep the budget by repeating it.
                    for (std::uint32_t k = 0; k <= t.splits; ++k) {
                        out.box[slot] = t.box;
                        out.prim[slot++] = prim;
                    }
                    continue;
                }
                Task lo, hi;
                detail::split_polygon(t.poly, axis, pos, lo.poly, hi.poly);
                AABB<T> lo_cut = t.box, hi_cut = t.box;
                lo_cut.max[std::size_t(axis)] = pos;
                hi_cut.min[std::size_t(axis)] = pos;
                lo.box = intersection(detail::conservative_bounds(lo.poly), lo_cut);
                hi.box = intersection(detail::conservative_bounds(hi.poly), hi_cut);
                if (lo.poly.n == 0 || lo.poly.overflow || lo.box.is_empty()) lo.box = lo_cut;
                if (hi.poly.n == 0 || hi.poly.overflow || hi.box.is_empty()) hi.box = hi_cut;
                const auto longest = [](const AABB<T>& b) {
                    const Vec3<T> d = b.diagonal();
                    return static_cast<double>(std::max(d.x, std::max(d.y, d.z)));
                };
                const double wl = longest(lo.box), wh = longest(hi.box);
                const std::uint32_t rest = t.splits - 1;
                std::uint32_t sl = rest / 2;
                if (wl + wh > 0.0)
                    sl = static_cast<std::uint32_t>(std::min<double>(rest, std::floor(rest * wl / (wl + wh) + 0.5)));
                lo.splits = sl;
                hi.splits = rest - sl;
                stack.push_back(hi);
                stack.push_back(lo);   // depth-first, lower half first
            }
        }
    });
    update_reference_bounds(out, ex);
    return out;
}

} // namespace dynbvh::presplit
