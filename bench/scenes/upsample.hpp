/// @file scenes/upsample.hpp
/// Separable Catmull-Rom resampling of a square grid of points: the cloth scenes
/// simulate a coarse grid and draw a fine one interpolated from it, so the per-frame
/// cost is O(fine vertices) however detailed the physics is.
#pragma once

#include <algorithm>
#include <array>
#include <cstdint>
#include <span>
#include <stdexcept>
#include <vector>

#include <dynbvh/vec.hpp>

namespace dynbvh::scenes {

/// Resamples a `coarse` x `coarse` row-major grid of points to `fine` x `fine` (both >= 2),
/// corners to corners. O(fine^2 + fine*coarse) per call, no allocation after construction.
class GridUpsampler {
public:
    GridUpsampler(std::uint32_t coarse, std::uint32_t fine) : coarse_(coarse), fine_(fine) {
        if (coarse < 2 || fine < 2) throw std::invalid_argument("dynbvh::scenes::GridUpsampler: grids need >= 2 points a side");
        taps_.resize(fine);
        for (std::uint32_t i = 0; i < fine; ++i) {
            const double x = double(i) * (coarse - 1) / (fine - 1);
            const auto c = std::min<std::uint32_t>(std::uint32_t(x), coarse - 2);
            const float t = float(x - c);
            Taps& tp = taps_[i];
            for (int k = 0; k < 4; ++k) tp.index[k] = std::uint32_t(std::clamp<std::int64_t>(std::int64_t(c) - 1 + k, 0, coarse - 1));
            const float t2 = t * t, t3 = t2 * t;
            tp.weight = {0.5f * (-t3 + 2 * t2 - t), 0.5f * (3 * t3 - 5 * t2 + 2), 0.5f * (-3 * t3 + 4 * t2 + t), 0.5f * (t3 - t2)};
        }
        rows_.resize(std::size_t(fine) * coarse);
    }

    std::uint32_t coarse() const noexcept { return coarse_; }
    std::uint32_t fine() const noexcept { return fine_; }

    /// `in`: coarse^2 points, `out`: fine^2 points.
    void apply(std::span<const Vec3f> in, std::span<Vec3f> out) {
        if (in.size() != std::size_t(coarse_) * coarse_ || out.size() != std::size_t(fine_) * fine_)
            throw std::invalid_argument("dynbvh::scenes::GridUpsampler::apply: wrong grid sizes");
        // Along rows (j) first: one coarse-wide row per fine row, then along columns.
        for (std::uint32_t j = 0; j < fine_; ++j) {
            const Taps& tv = taps_[j];
            const Vec3f* r0 = &in[std::size_t(tv.index[0]) * coarse_];
            const Vec3f* r1 = &in[std::size_t(tv.index[1]) * coarse_];
            const Vec3f* r2 = &in[std::size_t(tv.index[2]) * coarse_];
            const Vec3f* r3 = &in[std::size_t(tv.index[3]) * coarse_];
            Vec3f* row = &rows_[std::size_t(j) * coarse_];
            for (std::uint32_t i = 0; i < coarse_; ++i)
                row[i] = r0[i] * tv.weight[0] + r1[i] * tv.weight[1] + r2[i] * tv.weight[2] + r3[i] * tv.weight[3];
        }
        for (std::uint32_t j = 0; j < fine_; ++j) {
            const Vec3f* row = &rows_[std::size_t(j) * coarse_];
            Vec3f* o = &out[std::size_t(j) * fine_];
            for (std::uint32_t i = 0; i < fine_; ++i) {
                const Taps& tu = taps_[i];
                o[i] = row[tu.index[0]] * tu.weight[0] + row[tu.index[1]] * tu.weight[1] + row[tu.index[2]] * tu.weight[2] +
                       row[tu.index[3]] * tu.weight[3];
            }
        }
    }

private:
    struct Taps {
        std::array<std::uint32_t, 4> index{};
        std::array<float, 4> weight{};
    };
    std::uint32_t coarse_, fine_;
    std::vector<Taps> taps_;
    std::vector<Vec3f> rows_;
};

} // namespace dynbvh::scenes
