/// @file scenes/funnel.hpp
/// Built-in scene `funnel`, after the UNC "Funnel" benchmark: a cloth falls into a
/// glass funnel whose throat is plugged by a small ball, slides down the glass and
/// crumples (incoherent motion, topology kept). The funnel is transparent
/// (transmission 0.9, index of refraction 1.5): only refraction rays show it.
/// 150 frames (5 s at 30 fps: fall, slide, settle), about 18.5k triangles: cloth grid
/// 14,450 + double-walled funnel 2,072 + ball 1,740 + floor 200.
#pragma once

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdint>
#include <numbers>
#include <stdexcept>
#include <string>
#include <vector>

#include <dynbvh/io/scene.hpp>
#include "cloth.hpp"
#include "geometry.hpp"
#include "options.hpp"
#include "orbit_camera.hpp"
#include "random.hpp"
#include "upsample.hpp"

namespace dynbvh::scenes {

/// The funnel scene. Construction simulates a coarse cloth for every frame (~0.2 s);
/// `frame()` resamples it to the drawn resolution: O(triangles).
class Funnel final : public io::Scene {
public:
    static constexpr std::size_t frames = 150;
    static constexpr std::size_t reference_triangles = 18484;   ///< UNC funnel: cloth 14,464 + funnel 2,080 + ball 1,740 + floor 200
    static constexpr float fps = 30;
    // Funnel geometry (y up, axis through the origin): inner radius neck_radius from y_bottom to
    // y_neck (the spout), then a cone out to top_radius at y_top; glass `wall` thick.
    static constexpr float y_bottom = 1.135f, y_neck = 1.40f, y_top = 1.868f;
    static constexpr float neck_radius = 0.05f, top_radius = 0.72f, wall = 0.022f;
    static constexpr float ball_radius = 0.0566f;
    static constexpr float cloth_size = 0.8f;

    explicit Funnel(const BuiltinOptions& opt = {}) {
        validate(opt, "funnel");
        SplitMix64 rng(opt.seed);
        ball_centre_ = {0, 1.425f, 0};

        const std::uint32_t side = grid_side(14450, opt.scale, 4);
        fine_side_ = side + 1;
        cloth_faces_ = grid_faces(side, side);
        fine_.resize(std::size_t(fine_side_) * fine_side_);
        const std::uint32_t slices = std::max<std::uint32_t>(6, std::uint32_t(std::lround(74 * opt.scale)));
        glass_ = funnel_mesh(slices);
        const SphereResolution br = sphere_resolution(1740 * opt.scale);
        ball_ = uv_sphere(ball_centre_, ball_radius, br.slices, br.stacks);
        const std::uint32_t floor_side = grid_side(200, opt.scale, 1);
        floor_ = grid({-1.25f, 0, 1.25f}, {2.5f, 0, 0}, {0, 0, -2.5f}, floor_side, floor_side);

        ClothConfig cc;
        cc.resolution = coarse_res;
        cc.size = cloth_size;
        cc.substeps = 4;
        cc.iterations = 6;
        cc.gravity = {0, -0.0035f, 0};
        cc.damping = 0.99f;
        cc.shear_stiffness = 0.4f;
        cc.bend_stiffness = 0.04f;
        const float yaw = rng.uniformf(0, float(std::numbers::pi) / 2);
        const Vec3f u = normalize(Vec3f{std::cos(yaw), rng.uniformf(-0.25f, 0.25f), std::sin(yaw)});
        const Vec3f v = normalize(Vec3f{std::sin(yaw), rng.uniformf(-0.25f, 0.25f), -std::cos(yaw)});
        const Vec3f centre{rng.uniformf(-0.12f, 0.12f), 2.25f, rng.uniformf(-0.12f, 0.12f)};
        Cloth cloth(cc, centre, u, v);
        const std::size_t n = std::size_t(coarse_res) * coarse_res;
        coarse_.resize(frames * n);
        auto collide = [this](Vec3f& p, const Vec3f& prev, float, bool last) { collide_particle(p, prev, last, thickness); };
        for (std::size_t f = 0; f < frames; ++f) {
            if (f > 0) cloth.step(collide);
            std::copy(cloth.positions().begin(), cloth.positions().end(), coarse_.begin() + std::ptrdiff_t(f * n));
        }
        upsampler_ = GridUpsampler(coarse_res, fine_side_);

        // Triangles: cloth, glass, ball, floor.
        const std::size_t nc = cloth_faces_.size(), ng = glass_.faces.size(), nb = ball_.faces.size(), nf = floor_.faces.size();
        material_.assign(nc, 2);
        material_.insert(material_.end(), ng, 1);
        material_.insert(material_.end(), nb, 3);
        material_.insert(material_.end(), nf, 0);
        std::uint32_t first = 0;
        auto object = [&](const char* name, std::size_t count, bool animated) {
            io::ObjectInstance o{.name = name, .first_triangle = first, .triangle_count = std::uint32_t(count), .transform = {}, .animated = animated};
            first += std::uint32_t(count);
            return o;
        };
        objects_.push_back(object("cloth", nc, true));
        objects_.push_back(object("funnel", ng, false));
        objects_.push_back(object("ball", nb, false));
        objects_.push_back(object("floor", nf, false));

        info_.name = "funnel";
        info_.motion = io::Motion::incoherent;
        info_.topology_changes = false;
        info_.frames = frames;
        info_.materials = {io::Material{.name = "floor", .diffuse = {0.5f, 0.5f, 0.45f}},
                           io::Material{.name = "glass", .diffuse = {0.05f, 0.05f, 0.05f}, .specular = {0.08f, 0.08f, 0.08f},
                                        .shininess = 200, .transmission = 0.9f, .ior = 1.5f, .opacity = 0.1f, .illum = 7},
                           io::Material{.name = "cloth", .diffuse = {0.8f, 0.45f, 0.1f}},
                           io::Material{.name = "ball", .diffuse = {0.3f, 0.3f, 0.35f}}};
        info_.lights = {io::Light{.position = {1.5f, 4, 2}, .color = {1, 1, 1}}};
        camera_.target = {0, 1.45f, 0};
        camera_.distance = OrbitCamera::framing_distance(0.95f, camera_.fov_y_deg);
        camera_.elevation = 0.55f;
        camera_.start_angle = rng.uniformf(0, 2 * float(std::numbers::pi));
    }

    const io::SceneInfo& info() const override { return info_; }

    void frame(std::size_t i, io::Frame& out) override {
        if (i >= frames) throw std::out_of_range("dynbvh::scenes::Funnel: frame " + std::to_string(i) + " of " + std::to_string(frames));
        const std::size_t n = std::size_t(coarse_res) * coarse_res;
        upsampler_.apply(std::span<const Vec3f>(coarse_).subspan(i * n, n), fine_);
        for (Vec3f& p : fine_) collide_particle(p, p, false, 0.75f * thickness);
        const std::size_t nc = cloth_faces_.size(), ng = glass_.faces.size(), nb = ball_.faces.size(), nf = floor_.faces.size();
        out.triangles.resize(nc + ng + nb + nf);
        Trianglef* o = out.triangles.data();
        gather_triangles(fine_, cloth_faces_, o);
        gather_triangles(glass_.vertices, glass_.faces, o + nc);
        gather_triangles(ball_.vertices, ball_.faces, o + nc + ng);
        gather_triangles(floor_.vertices, floor_.faces, o + nc + ng + nb);
        out.material.assign(material_.begin(), material_.end());
        out.objects = objects_;
        out.camera = camera_.at(double(i));
        out.time = double(i) / fps;
    }

private:
    static constexpr std::uint32_t coarse_res = 24;
    static constexpr float thickness = 0.006f;

    /// The glass as a closed surface of revolution: outer wall up, rim, inner wall down, spout end.
    static IndexedMesh funnel_mesh(std::uint32_t slices) {
        std::vector<std::array<float, 2>> prof;
        auto cone = [](float t, float off) { return std::array<float, 2>{neck_radius + off + t * (top_radius - neck_radius), y_neck + t * (y_top - y_neck)}; };
        const float ym = 0.5f * (y_bottom + y_neck);
        prof.push_back({neck_radius + wall, y_bottom});
        prof.push_back({neck_radius + wall, ym});
        for (int k = 0; k <= 4; ++k) prof.push_back(cone(float(k) / 4, wall));
        for (int k = 4; k >= 0; --k) prof.push_back(cone(float(k) / 4, 0));
        prof.push_back({neck_radius, ym});
        prof.push_back({neck_radius, y_bottom});
        return revolve({0, 0, 0}, prof, slices, true);
    }

    /// Keeps a point `thick` away from the glass (on the side `prev` was on), out of the ball and above the floor.
    void collide_particle(Vec3f& p, const Vec3f& prev, bool friction, float thick) const noexcept {
        bool touched = false;
        // Glass: the wall's mid-surface in the (r, y) half-plane is a polyline: spout, then cone.
        const float half = 0.5f * wall + thick;
        const float r = std::sqrt(p.x * p.x + p.z * p.z), pr = std::sqrt(prev.x * prev.x + prev.z * prev.z);
        const std::array<std::array<float, 2>, 3> mid = {{{neck_radius + 0.5f * wall, y_bottom}, {neck_radius + 0.5f * wall, y_neck},
                                                          {top_radius + 0.5f * wall, y_top}}};
        float best = 1e30f, cr = 0, cy = 0, nr = 0, ny = 0;
        const bool near = p.y < y_top + half && p.y > y_bottom - half && r < top_radius + wall + half;
        for (int s = 0; s < (near ? 2 : 0); ++s) {
            const float ar = mid[s][0], ay = mid[s][1], er = mid[s + 1][0] - ar, ey = mid[s + 1][1] - ay;
            const float t = std::clamp(((r - ar) * er + (p.y - ay) * ey) / (er * er + ey * ey), 0.0f, 1.0f);
            const float qr = ar + t * er, qy = ay + t * ey, d2 = (r - qr) * (r - qr) + (p.y - qy) * (p.y - qy);
            if (d2 < best) {
                const float el = std::sqrt(er * er + ey * ey);
                best = d2; cr = qr; cy = qy; nr = -ey / el; ny = er / el;   // (nr, ny) points towards the axis
            }
        }
        if (best < half * half) {
            const float side = (pr - cr) * nr + (prev.y - cy) * ny >= 0 ? 1.0f : -1.0f;
            const float dist = std::sqrt(best);
            float dr = nr * side, dy = ny * side;
            if (dist > 1e-7f && ((r - cr) * nr + (p.y - cy) * ny) * side > 0) { dr = (r - cr) / dist; dy = (p.y - cy) / dist; }
            const float nr2 = std::max(0.0f, cr + dr * half);
            const float sx = r > 1e-7f ? p.x / r : 1.0f, sz = r > 1e-7f ? p.z / r : 0.0f;
            p = {sx * nr2, cy + dy * half, sz * nr2};
            touched = true;
        }
        const Vec3f d = p - ball_centre_;
        const float rb = ball_radius + thick, l2 = dot(d, d);
        if (l2 < rb * rb) {
            const float l = std::sqrt(l2);
            p = ball_centre_ + (l > 1e-7f ? d * (1 / l) : Vec3f{0, 1, 0}) * rb;
            touched = true;
        }
        if (p.y < thick) { p.y = thick; touched = true; }
        if (friction && touched) p -= (p - prev) * 0.06f;
    }

    io::SceneInfo info_;
    OrbitCamera camera_;
    std::vector<io::ObjectInstance> objects_;
    Vec3f ball_centre_;
    std::uint32_t fine_side_ = 0;
    std::vector<Vec3f> coarse_;          // frames x coarse_res^2
    GridUpsampler upsampler_{2, 2};
    std::vector<Vec3f> fine_;
    std::vector<Face> cloth_faces_;
    IndexedMesh glass_, ball_, floor_;
    std::vector<std::uint32_t> material_;
};

} // namespace dynbvh::scenes
