/// @file scenes/n_body.hpp
/// Built-in scene `n-body`, after the UNC "N-body" benchmark: 300 rigid balls fall,
/// bounce and spin among 5 static cylinders inside an invisible box (hierarchical
/// motion: every ball moves rigidly; topology kept). 76 frames, about 146k triangles:
/// 300 UV spheres of 480 triangles + 5 cylinders of 496.
#pragma once

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdint>
#include <numeric>
#include <stdexcept>
#include <string>
#include <vector>

#include <dynbvh/io/scene.hpp>
#include "geometry.hpp"
#include "options.hpp"
#include "orbit_camera.hpp"
#include "random.hpp"
#include "rigid.hpp"

namespace dynbvh::scenes {

/// The n-body scene. Construction simulates all balls for every frame (~10 ms);
/// `frame()` transforms each ball's template sphere: O(triangles).
class NBody final : public io::Scene {
public:
    static constexpr std::size_t frames = 76;
    static constexpr std::size_t balls = 300;
    static constexpr std::size_t reference_triangles = 146480;   ///< UNC balls16: 300 x 480 + 5 x 496
    static constexpr float box_half = 5.3f;                      ///< invisible walls at |x|, |z| = box_half; floor y = 0
    static constexpr float box_height = 11;                      ///< invisible lid
    static constexpr float fps = 30;

    explicit NBody(const BuiltinOptions& opt = {}) {
        validate(opt, "n-body");
        const SphereResolution sr = sphere_resolution(480 * opt.scale);
        sphere_ = uv_sphere({0, 0, 0}, 1, sr.slices, sr.stacks);
        const std::uint32_t cyl_slices = std::max<std::uint32_t>(6, std::uint32_t(std::lround(62 * opt.scale)));
        // Static bodies: (x, z, radius, height), the layout of the UNC scene.
        const std::array<std::array<float, 4>, 5> cyl = {{{0, 0, 2.5f, 3}, {-3, -3, 1.5f, 6}, {-3, 3, 0.75f, 3}, {3, -3, 1, 7}, {3, 3, 0.5f, 5}}};
        for (const auto& c : cyl) {
            cylinders_.push_back({c[0], c[1], c[2], c[3]});
            statics_.append(cylinder({c[0], 0, c[1]}, c[2], c[3], cyl_slices, 3));
        }
        simulate(opt.seed);

        const std::size_t per_ball = sphere_.faces.size();
        const std::size_t nb = balls * per_ball, ns = statics_.faces.size();
        SplitMix64 rng = SplitMix64::derive(opt.seed, 99);
        material_.resize(nb + ns);
        objects_.resize(balls + 1);
        for (std::size_t b = 0; b < balls; ++b) {
            const std::uint32_t m = 1 + rng.below(ball_colours);
            std::fill_n(material_.begin() + std::ptrdiff_t(b * per_ball), per_ball, m);
            objects_[b] = {.name = "ball" + std::to_string(b), .first_triangle = std::uint32_t(b * per_ball),
                           .triangle_count = std::uint32_t(per_ball), .transform = {}, .animated = true};
        }
        std::fill(material_.begin() + std::ptrdiff_t(nb), material_.end(), 0u);
        objects_[balls] = {.name = "pillars", .first_triangle = std::uint32_t(nb), .triangle_count = std::uint32_t(ns), .transform = {}, .animated = false};
        vertices_.resize(balls * sphere_.vertices.size());

        info_.name = "n-body";
        info_.motion = io::Motion::hierarchical;
        info_.topology_changes = false;
        info_.frames = frames;
        info_.materials = {io::Material{.name = "pillar", .diffuse = {0.6f, 0.6f, 0.6f}}};
        const std::array<Vec3f, ball_colours> colours = {{{0.8f, 0.2f, 0.15f}, {0.2f, 0.6f, 0.2f}, {0.2f, 0.3f, 0.8f}, {0.85f, 0.75f, 0.2f}, {0.7f, 0.3f, 0.7f}, {0.2f, 0.7f, 0.75f}}};
        for (std::size_t c = 0; c < ball_colours; ++c) info_.materials.push_back({.name = "ball" + std::to_string(c), .diffuse = colours[c]});
        info_.lights = {io::Light{.position = {8, 20, 12}, .color = {1, 1, 1}}};
        camera_.target = {0, 4.5f, 0};
        camera_.distance = OrbitCamera::framing_distance(9, camera_.fov_y_deg);
        camera_.elevation = 0.3f;
        camera_.start_angle = rng.uniformf(0, 6.2831853f);
    }

    const io::SceneInfo& info() const override { return info_; }

    void frame(std::size_t i, io::Frame& out) override {
        if (i >= frames) throw std::out_of_range("dynbvh::scenes::NBody: frame " + std::to_string(i) + " of " + std::to_string(frames));
        const std::size_t nv = sphere_.vertices.size(), per_ball = sphere_.faces.size();
        out.triangles.resize(balls * per_ball + statics_.faces.size());
        out.objects = objects_;
        for (std::size_t b = 0; b < balls; ++b) {
            const io::Transform t = ball_transform(i, b);
            out.objects[b].transform = t;
            Vec3f* v = &vertices_[b * nv];
            for (std::size_t k = 0; k < nv; ++k) v[k] = t.apply_point(sphere_.vertices[k]);
            gather_triangles(std::span<const Vec3f>(v, nv), sphere_.faces, out.triangles.data() + b * per_ball);
        }
        gather_triangles(statics_.vertices, statics_.faces, out.triangles.data() + balls * per_ball);
        out.material.assign(material_.begin(), material_.end());
        out.camera = camera_.at(double(i));
        out.time = double(i) / fps;
    }

    /// Ball radius (scene units).
    float radius(std::size_t ball) const { return radius_.at(ball); }

private:
    static constexpr std::size_t ball_colours = 6;
    static constexpr int substeps = 4;
    static constexpr float gravity = 0.03f;       // scene units per frame^2
    static constexpr float restitution = 0.92f;

    struct Cyl { float x, z, r, h; };
    struct State { Vec3f p, v, w; Quat q; };

    /// World transform of `ball` at frame `f`: the unit template sphere scaled by the radius, rotated, moved.
    io::Transform ball_transform(std::size_t f, std::size_t ball) const noexcept {
        const Sample& s = samples_[f * balls + ball];
        io::Transform t = Pose{s.q, {0, 0, 0}, s.p}.transform();
        for (int k : {0, 1, 2, 4, 5, 6, 8, 9, 10}) t.m[std::size_t(k)] *= radius_[ball];
        return t;
    }

    static void bounce(State& s, float r, Vec3f n, float depth) noexcept {
        s.p += n * depth;
        const float vn = dot(s.v, n);
        if (vn < 0) s.v -= n * ((1 + restitution) * vn);
        // Spin towards rolling on the contact.
        const Vec3f vt = s.v - n * dot(s.v, n);
        s.w = s.w * 0.8f + cross(n, vt) * (0.2f / r);
    }

    void simulate(std::uint64_t seed) {
        SplitMix64 rng = SplitMix64::derive(seed, 1);
        radius_.resize(balls);
        std::vector<State> st(balls);
        for (std::size_t b = 0; b < balls; ++b) {
            radius_[b] = rng.uniformf(0.22f, 0.38f);
            for (;;) {   // a start outside the pillars
                st[b].p = {rng.uniformf(-box_half + 0.4f, box_half - 0.4f), rng.uniformf(1.0f, box_height - 0.4f), rng.uniformf(-box_half + 0.4f, box_half - 0.4f)};
                if (inside_pillar(st[b].p, radius_[b]) < 0) break;
            }
            st[b].v = {rng.uniformf(-0.25f, 0.25f), rng.uniformf(-0.3f, 0.2f), rng.uniformf(-0.25f, 0.25f)};
            st[b].w = rng.unit_vector() * rng.uniformf(0, 0.3f);
            st[b].q = Quat::axis_angle(rng.unit_vector(), rng.uniformf(0, 6.2831853f));
        }
        samples_.resize(frames * balls);
        std::vector<std::uint32_t> order(balls);
        std::iota(order.begin(), order.end(), 0u);
        const float dt = 1.0f / substeps;
        for (std::size_t f = 0; f < frames; ++f) {
            for (std::size_t b = 0; b < balls; ++b) samples_[f * balls + b] = {st[b].p, st[b].q};
            for (int s = 0; s < substeps && f + 1 < frames; ++s) {
                for (State& x : st) {
                    x.v.y -= gravity * dt;
                    x.p += x.v * dt;
                    x.q = x.q.integrate(x.w, dt);
                }
                // Ball-ball contacts: sweep and prune along x (ties broken by index: the same order everywhere).
                std::sort(order.begin(), order.end(), [&](std::uint32_t a, std::uint32_t b) {
                    const float xa = st[a].p.x - radius_[a], xb = st[b].p.x - radius_[b];
                    return xa < xb || (xa == xb && a < b);
                });
                for (std::size_t oi = 0; oi < balls; ++oi) {
                    const std::uint32_t a = order[oi];
                    for (std::size_t oj = oi + 1; oj < balls; ++oj) {
                        const std::uint32_t b = order[oj];
                        if (st[b].p.x - radius_[b] > st[a].p.x + radius_[a]) break;
                        collide_balls(st[a], radius_[a], st[b], radius_[b]);
                    }
                }
                for (std::size_t b = 0; b < balls; ++b) collide_static(st[b], radius_[b]);
            }
        }
    }

    static void collide_balls(State& a, float ra, State& b, float rb) noexcept {
        const Vec3f d = b.p - a.p;
        const float d2 = dot(d, d), rr = ra + rb;
        if (d2 >= rr * rr || d2 < 1e-12f) return;
        const float dist = std::sqrt(d2);
        const Vec3f n = d * (1 / dist);
        const float ma = ra * ra * ra, mb = rb * rb * rb, overlap = rr - dist;
        a.p -= n * (overlap * mb / (ma + mb));
        b.p += n * (overlap * ma / (ma + mb));
        const float vrel = dot(b.v - a.v, n);
        if (vrel < 0) {
            const float j = -(1 + restitution) * vrel / (1 / ma + 1 / mb);
            a.v -= n * (j / ma);
            b.v += n * (j / mb);
        }
    }

    /// Index of the pillar that a ball at `p` with radius `r` overlaps, or -1.
    int inside_pillar(Vec3f p, float r) const noexcept {
        for (std::size_t c = 0; c < cylinders_.size(); ++c) {
            const Cyl& k = cylinders_[c];
            const float dx = p.x - k.x, dz = p.z - k.z;
            if (dx * dx + dz * dz < (k.r + r) * (k.r + r) && p.y < k.h + r) return int(c);
        }
        return -1;
    }

    void collide_static(State& s, float r) const noexcept {
        if (s.p.y < r) bounce(s, r, {0, 1, 0}, r - s.p.y);
        if (s.p.y > box_height - r) bounce(s, r, {0, -1, 0}, s.p.y - (box_height - r));
        if (s.p.x < -box_half + r) bounce(s, r, {1, 0, 0}, -box_half + r - s.p.x);
        if (s.p.x > box_half - r) bounce(s, r, {-1, 0, 0}, s.p.x - (box_half - r));
        if (s.p.z < -box_half + r) bounce(s, r, {0, 0, 1}, -box_half + r - s.p.z);
        if (s.p.z > box_half - r) bounce(s, r, {0, 0, -1}, s.p.z - (box_half - r));
        for (const Cyl& k : cylinders_) {
            // Closest point of the solid cylinder to the ball centre.
            const float dx = s.p.x - k.x, dz = s.p.z - k.z, rad = std::sqrt(dx * dx + dz * dz);
            const float s_r = rad > k.r ? k.r / rad : 1.0f;
            const Vec3f c{k.x + dx * s_r, std::clamp(s.p.y, 0.0f, k.h), k.z + dz * s_r};
            Vec3f d = s.p - c;
            const float l2 = dot(d, d);
            if (l2 >= r * r) continue;
            if (l2 > 1e-12f) {
                const float l = std::sqrt(l2);
                bounce(s, r, d * (1 / l), r - l);
            } else {   // centre inside the pillar: leave through the nearer of top and side
                const float up = k.h - s.p.y, side = k.r - rad;
                if (up < side || rad < 1e-6f) bounce(s, r, {0, 1, 0}, up + r);
                else bounce(s, r, {dx / rad, 0, dz / rad}, side + r);
            }
        }
    }

    struct Sample { Vec3f p; Quat q; };

    io::SceneInfo info_;
    OrbitCamera camera_;
    IndexedMesh sphere_, statics_;
    std::vector<Cyl> cylinders_;
    std::vector<float> radius_;
    std::vector<Sample> samples_;   // frames x balls
    std::vector<Vec3f> vertices_;
    std::vector<std::uint32_t> material_;
    std::vector<io::ObjectInstance> objects_;
};

} // namespace dynbvh::scenes
