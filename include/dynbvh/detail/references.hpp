// SPDX-License-Identifier: MIT
/// @file detail/references.hpp
/// The builders' common input: one reference per primitive (or per presplit fragment)
/// with its box and the triangle it stands for, plus the scene and centroid bounds.
/// Triangles with a NaN or infinite vertex are excluded here and counted: they can
/// never be hit, and keeping them would poison every box above them.
#pragma once

#include <algorithm>
#include <cstdint>
#include <limits>
#include <span>
#include <vector>

#include "../executor.hpp"
#include "scratch.hpp"
#include "triangle_source.hpp"
#include "../triangle.hpp"

namespace dynbvh {

/// Build references: parallel arrays, one entry per reference.
template <class T>
struct References {
    scratch_vector<AABB<T>> box;           ///< tight box of the reference (triangle or fragment)
    scratch_vector<std::uint32_t> prim;    ///< index of the user's triangle
    AABB<T> bounds;                        ///< union of all boxes
    AABB<T> centroid_bounds;               ///< union of all box centres
    std::size_t primitive_count = 0;       ///< triangles in the input
    std::size_t excluded = 0;              ///< input triangles skipped (non-finite vertices)
    bool repeats = false;                  ///< a triangle has several references (presplit fragments)

    std::size_t size() const noexcept { return box.size(); }
};

namespace detail {
template <class T>
struct BoundsPair {
    AABB<T> box, centroid;
    static BoundsPair combine(const BoundsPair& a, const BoundsPair& b) noexcept {
        return {merge(a.box, b.box), merge(a.centroid, b.centroid)};
    }
};
} // namespace detail

/// Recomputes `bounds` and `centroid_bounds` from `box`. O(n), parallel.
template <class T, class Exec>
void update_reference_bounds(References<T>& refs, const Exec& ex) {
    using BP = detail::BoundsPair<T>;
    const BP r = ex.reduce(
        std::size_t(0), refs.size(), BP{},
        [&](std::size_t i) {
            BP p;
            p.box = refs.box[i];
            p.centroid.extend(refs.box[i].center());
            return p;
        },
        [](const BP& a, const BP& b) { return BP::combine(a, b); });
    refs.bounds = r.box;
    refs.centroid_bounds = r.centroid;
}

/// One reference per finite triangle of `tris` (a std::span<const Triangle<T>> or a MeshView, see
/// detail/triangle_source.hpp), in input order. O(n), parallel; one pass over the triangles when all
/// are finite (the common case), a second compacting pass otherwise.
template <detail::triangle_source Source, class Exec>
References<detail::source_scalar_t<Source>> make_references(Source tris, const Exec& ex) {
    using T = detail::source_scalar_t<Source>;
    struct Acc {
        Vec3<T> lo, hi, clo, chi;   // bounds and centroid bounds, as corners (kept in registers)
        std::size_t bad;
    };
    constexpr T inf = std::numeric_limits<T>::infinity();
    const Acc empty{{inf, inf, inf}, {-inf, -inf, -inf}, {inf, inf, inf}, {-inf, -inf, -inf}, 0};
    References<T> refs;
    refs.primitive_count = tris.size();
    const std::size_t n = tris.size();
    refs.box.resize(n);
    refs.prim.resize(n);
    // A few tasks, each reducing its range in registers (a per-element reduction would merge whole
    // boxes per triangle), then a serial merge of the task results.
    const std::size_t tasks = std::clamp<std::size_t>(n / 4096, 1, 4 * ex.concurrency());
    const std::size_t chunk = (n + tasks - 1) / tasks;
    std::vector<Acc> partial(tasks, empty);
    ex.for_tasks(tasks, [&](std::size_t k) {
        Acc a = empty;
        AABB<T>* box = refs.box.data();
        std::uint32_t* prim = refs.prim.data();
        for (std::size_t i = std::min(n, k * chunk), e = std::min(n, i + chunk); i < e; ++i) {
            const Triangle<T>& t = tris[i];   // (a view's triangle by value, bound here)
            const Vec3<T> lo = dynbvh::min(dynbvh::min(t.p0, t.p1), t.p2);
            const Vec3<T> hi = dynbvh::max(dynbvh::max(t.p0, t.p1), t.p2);
            box[i] = {lo, hi};
            prim[i] = static_cast<std::uint32_t>(i);
            if (t.is_finite()) {   // (not from lo, hi: min/max above may drop a NaN)
                const Vec3<T> c = (lo + hi) * T(0.5);
                a.lo = dynbvh::min(a.lo, lo);
                a.hi = dynbvh::max(a.hi, hi);
                a.clo = dynbvh::min(a.clo, c);
                a.chi = dynbvh::max(a.chi, c);
            } else {
                ++a.bad;
            }
        }
        partial[k] = a;
    });
    Acc acc = empty;
    for (const Acc& a : partial)
        acc = {dynbvh::min(acc.lo, a.lo), dynbvh::max(acc.hi, a.hi), dynbvh::min(acc.clo, a.clo), dynbvh::max(acc.chi, a.chi),
               acc.bad + a.bad};
    refs.excluded = acc.bad;
    refs.bounds = {acc.lo, acc.hi};
    refs.centroid_bounds = {acc.clo, acc.chi};
    if (acc.bad != 0) {
        std::size_t k = 0;
        for (std::size_t i = 0; i < n; ++i)
            if (tris[i].is_finite()) {
                refs.box[k] = refs.box[i];
                refs.prim[k++] = static_cast<std::uint32_t>(i);
            }
        refs.box.resize(k);
        refs.prim.resize(k);
    }
    return refs;
}

} // namespace dynbvh
