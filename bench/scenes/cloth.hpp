/// @file scenes/cloth.hpp
/// A cheap cloth for the built-in scenes: position-based dynamics (Müller et al. 2007,
/// "Position based dynamics") on a square grid of particles with Verlet integration,
/// structural, shear and bending distance constraints, and obstacles given as a
/// projection callback. Meant to run on a coarse grid (tens of particles a side);
/// the scenes draw a fine grid interpolated from it (upsample.hpp).
#pragma once

#include <cmath>
#include <cstdint>
#include <span>
#include <stdexcept>
#include <vector>

#include <dynbvh/vec.hpp>

namespace dynbvh::scenes {

/// Cloth knobs. Time is measured in frames, lengths in scene units.
struct ClothConfig {
    std::uint32_t resolution = 40;    ///< particles per side (>= 2)
    float size = 1;                   ///< rest side length of the square
    std::uint32_t substeps = 4;       ///< integration steps per frame
    std::uint32_t iterations = 6;     ///< constraint passes per substep (more = stiffer)
    Vec3f gravity{0, -0.05f, 0};      ///< acceleration, scene units per frame^2
    float damping = 0.995f;           ///< fraction of velocity kept per substep
    float shear_stiffness = 0.7f;     ///< 0..1, diagonal constraints
    float bend_stiffness = 0.2f;      ///< 0..1, constraints that skip one particle
};

/// A square cloth, simulated one frame at a time. O(resolution^2 * substeps * iterations) per frame.
class Cloth {
public:
    /// Flat square centred on `centre`, spanned by the unit vectors `u` (columns) and `v` (rows),
    /// moving with `velocity` (scene units per frame). Particle (i, j) is at index j*resolution + i.
    Cloth(const ClothConfig& cfg, Vec3f centre, Vec3f u, Vec3f v, Vec3f velocity = {0, 0, 0}) : cfg_(cfg) {
        const std::uint32_t n = cfg.resolution;
        if (n < 2 || cfg.substeps < 1) throw std::invalid_argument("dynbvh::scenes::Cloth: needs resolution >= 2 and substeps >= 1");
        const float h = cfg.size / float(n - 1);
        x_.resize(std::size_t(n) * n);
        prev_.resize(x_.size());
        const float sub_dt = 1.0f / float(cfg.substeps);
        for (std::uint32_t j = 0; j < n; ++j)
            for (std::uint32_t i = 0; i < n; ++i) {
                const Vec3f p = centre + u * (h * float(i) - 0.5f * cfg.size) + v * (h * float(j) - 0.5f * cfg.size);
                x_[idx(i, j)] = p;
                prev_[idx(i, j)] = p - velocity * sub_dt;
            }
        auto add = [&](std::uint32_t i0, std::uint32_t j0, std::uint32_t i1, std::uint32_t j1, float k) {
            if (i1 >= n || j1 >= n) return;
            links_.push_back({idx(i0, j0), idx(i1, j1), length(x_[idx(i1, j1)] - x_[idx(i0, j0)]), k});
        };
        for (std::uint32_t j = 0; j < n; ++j)
            for (std::uint32_t i = 0; i < n; ++i) { add(i, j, i + 1, j, 1); add(i, j, i, j + 1, 1); }
        for (std::uint32_t j = 0; j < n; ++j)
            for (std::uint32_t i = 0; i < n; ++i) {
                add(i, j, i + 1, j + 1, cfg.shear_stiffness);
                if (i > 0) add(i, j, i - 1, j + 1, cfg.shear_stiffness);
            }
        for (std::uint32_t j = 0; j < n; ++j)
            for (std::uint32_t i = 0; i < n; ++i) { add(i, j, i + 2, j, cfg.bend_stiffness); add(i, j, i, j + 2, cfg.bend_stiffness); }
        colour_links();
    }

    std::uint32_t resolution() const noexcept { return cfg_.resolution; }
    std::span<const Vec3f> positions() const noexcept { return x_; }
    /// Frames simulated so far.
    std::uint64_t frame() const noexcept { return frame_; }

    /// Advances one frame. `collide(Vec3f& p, const Vec3f& prev, float t, bool last)` moves particle `p`
    /// out of every obstacle at time `t` (frames since the start); `prev` is where the particle was at
    /// the start of the substep, and `last` marks the substep's final call, where friction belongs.
    template <class Collide>
    void step(Collide&& collide) {
        const float dt = 1.0f / float(cfg_.substeps);
        const Vec3f g = cfg_.gravity * (dt * dt);
        for (std::uint32_t s = 0; s < cfg_.substeps; ++s) {
            const float t = float(frame_) + float(s + 1) * dt;
            for (std::size_t p = 0; p < x_.size(); ++p) {
                const Vec3f v = (x_[p] - prev_[p]) * cfg_.damping;
                prev_[p] = x_[p];
                x_[p] += v + g;
            }
            for (std::uint32_t it = 0; it < cfg_.iterations; ++it) {
                for (const Link& l : links_) {
                    const Vec3f d = x_[l.b] - x_[l.a];
                    const float len = length(d);
                    if (len < 1e-12f) continue;
                    const Vec3f c = d * (0.5f * l.k * (len - l.rest) / len);
                    x_[l.a] += c;
                    x_[l.b] -= c;
                }
                const bool last = it + 1 == cfg_.iterations;
                for (std::size_t p = 0; p < x_.size(); ++p) collide(x_[p], prev_[p], t, last);
            }
        }
        ++frame_;
    }

private:
    struct Link {
        std::uint32_t a, b;
        float rest, k;
    };
    std::uint32_t idx(std::uint32_t i, std::uint32_t j) const noexcept { return j * cfg_.resolution + i; }

    // Greedy colouring, then links grouped by colour: consecutive links share no particle, so the
    // Gauss-Seidel sweep has no dependency chains and runs several times faster.
    void colour_links() {
        std::vector<std::vector<bool>> used;
        std::vector<std::uint32_t> colour(links_.size());
        for (std::size_t l = 0; l < links_.size(); ++l) {
            std::uint32_t c = 0;
            for (; c < used.size(); ++c)
                if (!used[c][links_[l].a] && !used[c][links_[l].b]) break;
            if (c == used.size()) used.emplace_back(x_.size(), false);
            used[c][links_[l].a] = used[c][links_[l].b] = true;
            colour[l] = c;
        }
        std::vector<Link> sorted;
        sorted.reserve(links_.size());
        for (std::uint32_t c = 0; c < used.size(); ++c)
            for (std::size_t l = 0; l < links_.size(); ++l)
                if (colour[l] == c) sorted.push_back(links_[l]);
        links_ = std::move(sorted);
    }

    ClothConfig cfg_;
    std::vector<Vec3f> x_, prev_;
    std::vector<Link> links_;
    std::uint64_t frame_ = 0;
};

} // namespace dynbvh::scenes
