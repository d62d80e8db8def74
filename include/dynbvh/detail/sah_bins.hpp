// SPDX-License-Identifier: MIT
/// @file detail/sah_bins.hpp
/// The binning step of top-down SAH builds (Wald 2007): per-axis bins of counts and boxes, the map
/// from a centre to its bin, and the cheapest bin boundary. Shared by binned_sah.hpp (bins of
/// references) and detail/sah_top.hpp (bins of subtrees weighted by their references).
#pragma once

#include <cstddef>
#include <cstdint>
#include <limits>
#include <vector>

#include "../aabb.hpp"
#include "../vec.hpp"

namespace dynbvh::detail {

/// Per-axis bins: reference count (or weight) and box bounds.
template <class T>
struct Bins {
    std::uint32_t k = 0;
    std::vector<std::uint32_t> count;   ///< 3 * k
    std::vector<AABB<T>> box;           ///< 3 * k

    explicit Bins(std::uint32_t bins = 0) : k(bins), count(3 * std::size_t(bins), 0), box(3 * std::size_t(bins)) {}
    /// Empties the bins and uses the first `bins` of the capacity per axis.
    void reset(std::uint32_t bins) {
        k = bins;
        count.assign(3 * std::size_t(bins), 0u);
        box.assign(3 * std::size_t(bins), AABB<T>{});
    }
    void merge(const Bins& o) {
        for (std::size_t b = 0; b < count.size(); ++b) {
            count[b] += o.count[b];
            box[b].extend(o.box[b]);
        }
    }
};

/// Maps a centre to its bin on each axis. Identical arithmetic in binning and partitioning, in
/// double: a float extent near FLT_MAX would overflow, and bins / extent would overflow for a
/// subnormal one (scenes at 1e-40), putting every centre in one bin.
template <class T>
struct Binner {
    Vec3<T> origin{};
    double scale[3] = {0, 0, 0};
    std::uint32_t k = 0;

    Binner(const AABB<T>& centroids, std::uint32_t bins) : origin(centroids.min), k(bins) {
        for (std::size_t a = 0; a < 3; ++a) {
            const double ext = double(centroids.max[a]) - double(centroids.min[a]);
            scale[a] = ext > 0 ? double(bins) / ext : 0;
        }
    }
    std::uint32_t bin(const Vec3<T>& c, std::size_t a) const noexcept {
        const double f = (double(c[a]) - double(origin[a])) * scale[a];
        if (!(f > 0)) return 0;
        return f >= double(k - 1) ? k - 1 : static_cast<std::uint32_t>(f);
    }
};

struct Split {
    int axis = -1;              ///< -1: no binned split, use a median split
    std::uint32_t bin = 0;      ///< items in bins [0, bin) go left
};

/// Cheapest bin boundary by SAH (area * count per side; the constant terms cancel). Scratch `right`
/// holds suffix areas. Ties keep the lowest axis and boundary, so the choice is deterministic.
template <class T>
Split best_split(const Bins<T>& bins, const AABB<T>& centroids, std::vector<double>& right) {
    Split best;
    double best_cost = std::numeric_limits<double>::infinity();
    const std::uint32_t k = bins.k;
    right.resize(k);
    const Vec3<T> ext = centroids.diagonal();
    for (int a = 0; a < 3; ++a) {
        if (!(ext[std::size_t(a)] > T(0))) continue;
        const std::uint32_t* cnt = bins.count.data() + std::size_t(a) * k;
        const AABB<T>* box = bins.box.data() + std::size_t(a) * k;
        std::uint64_t total = 0;
        for (std::uint32_t b = 0; b < k; ++b) total += cnt[b];
        AABB<T> acc;
        std::uint64_t n = 0;
        for (std::uint32_t b = k - 1; b > 0; --b) {
            acc.extend(box[b]);
            n += cnt[b];
            right[b] = acc.template half_area_in<double>() * static_cast<double>(n);
        }
        acc = AABB<T>{};
        n = 0;
        for (std::uint32_t b = 1; b < k; ++b) {
            acc.extend(box[b - 1]);
            n += cnt[b - 1];
            const double cost = acc.template half_area_in<double>() * static_cast<double>(n) + right[b];
            if (cost < best_cost && n > 0 && n < total) {
                best_cost = cost;
                best = {a, b};
            }
        }
    }
    return best;
}

} // namespace dynbvh::detail
