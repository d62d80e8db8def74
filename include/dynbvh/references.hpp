/// @file references.hpp
/// The builders' common input: one reference per primitive (or per presplit fragment)
/// with its box and the triangle it stands for, plus the scene and centroid bounds.
/// Triangles with a NaN or infinite vertex are excluded here and counted: they can
/// never be hit, and keeping them would poison every box above them.
#pragma once

#include <cstdint>
#include <span>
#include <vector>

#include "executor.hpp"
#include "scratch.hpp"
#include "triangle.hpp"

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

/// One reference per finite triangle, in input order. O(n), parallel; one pass over the
/// triangles when all are finite (the common case), a second compacting pass otherwise.
template <class T, class Exec>
References<T> make_references(std::span<const Triangle<T>> tris, const Exec& ex) {
    using BP = detail::BoundsPair<T>;
    struct Acc {
        BP bounds;
        std::size_t bad = 0;
    };
    References<T> refs;
    refs.primitive_count = tris.size();
    const std::size_t n = tris.size();
    refs.box.resize(n);
    refs.prim.resize(n);
    const Acc acc = ex.reduce(
        std::size_t(0), n, Acc{},
        [&](std::size_t i) {
            Acc a;
            const AABB<T> b = tris[i].bounds();
            refs.box[i] = b;
            refs.prim[i] = static_cast<std::uint32_t>(i);
            if (tris[i].is_finite()) {
                a.bounds.box = b;
                a.bounds.centroid.extend(b.center());
            } else {
                a.bad = 1;
            }
            return a;
        },
        [](const Acc& x, const Acc& y) { return Acc{BP::combine(x.bounds, y.bounds), x.bad + y.bad}; });
    refs.excluded = acc.bad;
    refs.bounds = acc.bounds.box;
    refs.centroid_bounds = acc.bounds.centroid;
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
