/// @file scenes/cloth_ball.hpp
/// Built-in scene `cloth-ball`, after the UNC "Cloth-ball" benchmark: a square cloth
/// falls onto a ball held above a floor, drapes over it, and is then dragged round
/// by the ball spinning about its vertical axis (incoherent motion, topology kept).
/// 94 frames, about 92k triangles: cloth grid + 20x20 UV-sphere ball + an 8-triangle floor.
#pragma once

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
#include "rigid.hpp"
#include "upsample.hpp"

namespace dynbvh::scenes {

/// The cloth-ball scene. Construction simulates a coarse cloth for every frame
/// (scale-independent, ~0.3 s); `frame()` resamples it to the drawn resolution: O(triangles).
class ClothBall final : public io::Scene {
public:
    static constexpr std::size_t frames = 94;
    static constexpr std::size_t reference_triangles = 92230;   ///< UNC cloth_ball: cloth 91,470 + ball 760
    static constexpr float ball_radius = 5;
    static constexpr float floor_half = 16;
    static constexpr float cloth_size = 28;
    static constexpr float fps = 30;

    explicit ClothBall(const BuiltinOptions& opt = {}) {
        validate(opt, "cloth-ball");
        SplitMix64 rng(opt.seed);
        ball_centre_ = {0, 6.7f, 0};
        spin_start_ = 34 + rng.uniformf(-2, 2);
        spin_full_ = spin_start_ + 14;
        spin_rate_ = rng.uniformf(0.05f, 0.06f) * (rng.uniform() < 0.5 ? -1.0f : 1.0f);

        // Drawn meshes: cloth grid of `side` quads a side, ball, floor (2x2 quads).
        const std::uint32_t side = grid_side(double(reference_triangles - 760 - 8), opt.scale, 4);
        const SphereResolution ball_res = sphere_resolution(760 * opt.scale);
        fine_side_ = side + 1;
        cloth_faces_ = grid_faces(side, side);
        ball_ = uv_sphere(ball_centre_, ball_radius, ball_res.slices, ball_res.stacks);
        floor_ = grid({-floor_half, 0, floor_half}, {2 * floor_half, 0, 0}, {0, 0, -2 * floor_half}, 2, 2);
        ball_now_.resize(ball_.vertices.size());
        fine_.resize(std::size_t(fine_side_) * fine_side_);

        // Coarse simulation, stored per frame.
        ClothConfig cc;
        cc.resolution = coarse_res;
        cc.size = cloth_size;
        cc.substeps = substeps;
        cc.iterations = 6;
        cc.gravity = {0, -0.06f, 0};
        const float yaw = rng.uniformf(0, float(std::numbers::pi) / 2), tilt = rng.uniformf(-0.08f, 0.08f);
        const Vec3f u{std::cos(yaw), tilt, std::sin(yaw)};
        const Vec3f v = normalize(cross(u, Vec3f{0, 1, 0}) * -1.0f + Vec3f{0, rng.uniformf(-0.08f, 0.08f), 0});
        const Vec3f centre{rng.uniformf(-1, 1), ball_centre_.y + ball_radius + 2.5f, rng.uniformf(-1, 1)};
        Cloth cloth(cc, centre, normalize(u), v);
        const std::size_t n = std::size_t(coarse_res) * coarse_res;
        coarse_.resize(frames * n);
        auto collide = [this](Vec3f& p, const Vec3f& prev, float t, bool last) { collide_particle(p, prev, t, last, thickness); };
        for (std::size_t f = 0; f < frames; ++f) {
            if (f > 0) cloth.step(collide);
            std::copy(cloth.positions().begin(), cloth.positions().end(), coarse_.begin() + std::ptrdiff_t(f * n));
        }
        upsampler_ = GridUpsampler(coarse_res, fine_side_);

        // Materials: 0 floor, 1 ball, 2 cloth; triangles are cloth, ball, floor in that order.
        const std::size_t nc = cloth_faces_.size(), nb = ball_.faces.size(), nf = floor_.faces.size();
        material_.assign(nc, 2);
        material_.insert(material_.end(), nb, 1);
        material_.insert(material_.end(), nf, 0);
        info_.name = "cloth-ball";
        info_.motion = io::Motion::incoherent;
        info_.topology_changes = false;
        info_.frames = frames;
        info_.materials = {io::Material{.name = "floor", .diffuse = {0.55f, 0.55f, 0.5f}},
                           io::Material{.name = "ball", .diffuse = {0.75f, 0.15f, 0.1f}},
                           io::Material{.name = "cloth", .diffuse = {0.2f, 0.35f, 0.75f}}};
        info_.lights = {io::Light{.position = {18, 40, 24}, .color = {1, 1, 1}}};
        camera_.target = {0, 5, 0};
        camera_.distance = OrbitCamera::framing_distance(17, camera_.fov_y_deg);
        camera_.elevation = 0.5f;
        camera_.start_angle = rng.uniformf(0, 2 * float(std::numbers::pi));
        objects_ = {io::ObjectInstance{.name = "cloth", .first_triangle = 0, .triangle_count = std::uint32_t(nc), .transform = {}, .animated = true},
                    io::ObjectInstance{.name = "ball", .first_triangle = std::uint32_t(nc), .triangle_count = std::uint32_t(nb), .transform = {}, .animated = true},
                    io::ObjectInstance{.name = "floor", .first_triangle = std::uint32_t(nc + nb), .triangle_count = std::uint32_t(nf), .transform = {}, .animated = false}};
    }

    const io::SceneInfo& info() const override { return info_; }

    void frame(std::size_t i, io::Frame& out) override {
        if (i >= frames) throw std::out_of_range("dynbvh::scenes::ClothBall: frame " + std::to_string(i) + " of " + std::to_string(frames));
        const std::size_t n = std::size_t(coarse_res) * coarse_res;
        upsampler_.apply(std::span<const Vec3f>(coarse_).subspan(i * n, n), fine_);
        const float t = float(i);
        for (Vec3f& p : fine_) collide_particle(p, p, t, false, 0.75f * thickness);
        const std::size_t nc = cloth_faces_.size(), nb = ball_.faces.size(), nf = floor_.faces.size();
        out.triangles.resize(nc + nb + nf);
        gather_triangles(fine_, cloth_faces_, out.triangles.data());
        const Pose pose{Quat::axis_angle({0, 1, 0}, spin_angle(t)), ball_centre_, ball_centre_};
        const io::Transform tr = pose.transform();
        for (std::size_t k = 0; k < ball_.vertices.size(); ++k) ball_now_[k] = tr.apply_point(ball_.vertices[k]);
        gather_triangles(ball_now_, ball_.faces, out.triangles.data() + nc);
        gather_triangles(floor_.vertices, floor_.faces, out.triangles.data() + nc + nb);
        out.material.assign(material_.begin(), material_.end());
        out.objects = objects_;
        out.objects[1].transform = tr;
        out.camera = camera_.at(double(i));
        out.time = double(i) / fps;
    }

private:
    static constexpr std::uint32_t coarse_res = 40;
    static constexpr std::uint32_t substeps = 4;
    static constexpr float thickness = 0.12f;

    /// Ball rotation angle (radians) at time t (frames): still, then ramping up to spin_rate_.
    float spin_angle(float t) const noexcept {
        if (t <= spin_start_) return 0;
        const float ramp = spin_full_ - spin_start_;
        if (t <= spin_full_) return spin_rate_ * (t - spin_start_) * (t - spin_start_) / (2 * ramp);
        return spin_rate_ * (0.5f * ramp + (t - spin_full_));
    }

    void collide_particle(Vec3f& p, const Vec3f& prev, float t, bool friction, float thick) const noexcept {
        const Vec3f d = p - ball_centre_;
        const float r = ball_radius + thick, l2 = dot(d, d);
        if (l2 < r * r) {
            const float l = std::sqrt(l2);
            const Vec3f nrm = l > 1e-6f ? d * (1 / l) : Vec3f{0, 1, 0};
            p = ball_centre_ + nrm * r;
            if (friction) {
                // Sticky contact: the particle follows the spinning surface, keeping a little slip.
                const float da = spin_angle(t) - spin_angle(t - 1.0f / substeps);
                const Vec3f rel = p - ball_centre_;
                const float c = std::cos(da), s = std::sin(da);
                const Vec3f surf = Vec3f{c * rel.x - s * rel.z, rel.y, s * rel.x + c * rel.z} - rel;
                Vec3f slip = (p - prev) - surf;
                slip -= nrm * dot(slip, nrm);
                p -= slip * 0.8f;
            }
        }
        if (p.y < thick) {
            p.y = thick;
            if (friction) {
                p.x -= (p.x - prev.x) * 0.6f;
                p.z -= (p.z - prev.z) * 0.6f;
            }
        }
    }

    io::SceneInfo info_;
    OrbitCamera camera_;
    std::vector<io::ObjectInstance> objects_;
    Vec3f ball_centre_;
    float spin_start_ = 0, spin_full_ = 0, spin_rate_ = 0;
    std::uint32_t fine_side_ = 0;
    std::vector<Vec3f> coarse_;          // frames x coarse_res^2
    GridUpsampler upsampler_{2, 2};
    std::vector<Vec3f> fine_;
    std::vector<Face> cloth_faces_;
    IndexedMesh ball_, floor_;
    std::vector<Vec3f> ball_now_;
    std::vector<std::uint32_t> material_;
};

} // namespace dynbvh::scenes
