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

/// One reference per finite triangle, in input order. O(n), parallel.
template <class T, class Exec>
References<T> make_references(std::span<const Triangle<T>> tris, const Exec& ex) {
    References<T> refs;
    refs.primitive_count = tris.size();
    const std::size_t n = tris.size();
    // Fast path: all finite (the common case) avoids the compaction pass.
    const std::size_t bad = ex.reduce(
        std::size_t(0), n, std::size_t(0), [&](std::size_t i) { return tris[i].is_finite() ? std::size_t(0) : std::size_t(1); },
        [](std::size_t a, std::size_t b) { return a + b; });
    refs.excluded = bad;
    if (bad == 0) {
        refs.box.resize(n);
        refs.prim.resize(n);
        ex.for_each(0, n, [&](std::size_t i) {
            refs.box[i] = tris[i].bounds();
            refs.prim[i] = static_cast<std::uint32_t>(i);
        });
    } else {
        refs.box.reserve(n - bad);
        refs.prim.reserve(n - bad);
        for (std::size_t i = 0; i < n; ++i)
            if (tris[i].is_finite()) {
                refs.box.push_back(tris[i].bounds());
                refs.prim.push_back(static_cast<std::uint32_t>(i));
            }
    }
    update_reference_bounds(refs, ex);
    return refs;
}

} // namespace dynbvh
