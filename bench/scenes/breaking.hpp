/// @file scenes/breaking.hpp
/// Built-in scenes `breaking` and `large-breaking`, after the UNC "Dragon" (a bunny
/// falls and breaks a dragon; 252k triangles, 16 frames) and "Lion" (1.6M triangles,
/// 45 frames) benchmarks. A bunny-like blob falls onto a long dragon-like body lying
/// on a floor and shatters it: at the impact the body around the blow breaks into
/// rigid shards that fly apart while the rest stays as two remnants; a few frames
/// later the shards nearest the blow break again. Every break closes the shards with
/// fracture faces, so the triangle set really changes (semi-hierarchical motion,
/// topology changes).
#pragma once

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdint>
#include <limits>
#include <numbers>
#include <numeric>
#include <stdexcept>
#include <string>
#include <string_view>
#include <vector>

#include <dynbvh/io/scene.hpp>
#include "geometry.hpp"
#include "options.hpp"
#include "orbit_camera.hpp"
#include "random.hpp"
#include "rigid.hpp"

namespace dynbvh::scenes {

/// Knobs of the breaking scenes; the defaults are `breaking`, `BreakingConfig::large()` is `large-breaking`.
struct BreakingConfig {
    std::string_view name = "breaking";
    std::size_t frames = 16;
    std::size_t blob_triangles = 69451;     ///< the falling object (the Stanford bunny's count)
    std::size_t body_triangles = 182400;    ///< the object that breaks; with the blob ~252k at frame 0
    std::size_t impact_frame = 5;           ///< first frame drawn broken
    std::size_t second_break = 4;           ///< frames after the impact when the nearest shards break again
    std::uint32_t cells_along = 24;         ///< shards along the body ...
    std::uint32_t cells_around = 4;         ///< ... and around it (Voronoi cells of jittered seeds)
    std::uint32_t split = 2;                ///< a shard that breaks again splits into about split^2 pieces
    float broken_radius = 0.3f;             ///< shards within this fraction of the body length of the blow break off
    float fine_radius = 0.14f;              ///< ... and within this one break again
    float gravity = 0.08f;                  ///< scene units per frame^2 (the body is 10 units long)
    float shard_speed = 1;                  ///< shard launch speed, relative to the blob's speed at the blow

    /// The `large-breaking` scene: 1.6M triangles, 45 frames.
    static constexpr BreakingConfig large() noexcept {
        BreakingConfig c;
        c.name = "large-breaking";
        c.frames = 45;
        c.blob_triangles = 200000;
        c.body_triangles = 1400000;
        c.impact_frame = 10;
        c.second_break = 6;
        c.cells_along = 40;
        c.cells_around = 6;
        c.split = 3;
        c.broken_radius = 0.34f;
        c.fine_radius = 0.17f;
        c.gravity = 0.03f;
        c.shard_speed = 0.6f;
        return c;
    }
};

/// A breaking scene. Construction builds the meshes, the shards with their fracture faces
/// for each stage of breaking and simulates all rigid bodies (O(n log n), ~1 s per million
/// triangles); `frame()` transforms each body's vertices and gathers: O(triangles).
class Breaking final : public io::Scene {
public:
    static constexpr float fps = 30;
    static constexpr float body_length = 10;
    static constexpr float floor_half = 9;

    explicit Breaking(const BreakingConfig& cfg = {}, const BuiltinOptions& opt = {}) : cfg_(cfg) {
        validate(opt, cfg.name);
        if (cfg.frames < 2 || cfg.impact_frame < 1 || cfg.impact_frame >= cfg.frames || cfg.cells_along < 1 || cfg.cells_around < 3 ||
            cfg.split < 1)
            throw std::invalid_argument("dynbvh::scenes::Breaking: inconsistent BreakingConfig for " + std::string(cfg.name));
        SplitMix64 rng(opt.seed);
        Tube body = make_body(std::max<double>(64, double(cfg.body_triangles) * opt.scale), rng);
        IndexedMesh blob = make_blob(std::max<double>(32, double(cfg.blob_triangles) * opt.scale), rng);

        // Floor: 4 large triangles.
        floor_ = grid({-floor_half, 0, floor_half}, {2 * floor_half, 0, 0}, {0, 0, -2 * floor_half}, 1, 1);
        floor_.vertices.push_back({0, 0, 0});
        floor_.faces = {{0, 1, 4}, {1, 3, 4}, {3, 2, 4}, {2, 0, 4}};

        // The blow: a point on the body's back near its middle.
        const Vec3f spine = body.spine_at(0.5f + rng.uniformf(-0.08f, 0.08f));
        float top = 0;
        for (const Vec3f& v : body.mesh.vertices) {
            const float dx = v.x - spine.x, dz = v.z - spine.z;
            if (dx * dx + dz * dz < 0.25f * body.radius * body.radius) top = std::max(top, v.y);
        }
        impact_ = {spine.x, top, spine.z};

        build_pieces(body, rng);
        build_states();
        add_blob(blob);
        simulate(rng);
        describe(rng);
    }

    const io::SceneInfo& info() const override { return info_; }

    void frame(std::size_t i, io::Frame& out) override {
        if (i >= cfg_.frames)
            throw std::out_of_range("dynbvh::scenes::Breaking: frame " + std::to_string(i) + " of " + std::to_string(cfg_.frames));
        const State& st = states_[state_of_frame(i)];
        const io::Transform* poses = &poses_[i * bodies_.size()];
        std::size_t total = blob_faces_.size() + floor_.faces.size() + st.caps.size();
        for (std::uint32_t b : st.bodies)
            for (std::uint32_t p : bodies_[b].pieces) total += piece_face_begin_[p + 1] - piece_face_begin_[p];
        out.triangles.resize(total);
        out.material.resize(total);
        out.objects.resize(st.bodies.size() + 2);
        Trianglef* o = out.triangles.data();
        std::uint32_t* m = out.material.data();
        std::size_t at = 0;
        auto object = [&](std::size_t k, const std::string& name, std::size_t first, const io::Transform& t, bool animated) {
            io::ObjectInstance& obj = out.objects[k];
            if (obj.name != name) obj.name = name;
            obj.first_triangle = std::uint32_t(first);
            obj.triangle_count = std::uint32_t(at - first);
            obj.transform = t;
            obj.animated = animated;
        };
        // Blob.
        {
            const io::Transform& t = poses[0];
            for (std::uint32_t v = blob_vertex_begin_; v < blob_vertex_end_; ++v) now_[v] = t.apply_point(rest_[v]);
            gather_triangles(now_, blob_faces_, o);
            std::fill_n(m, blob_faces_.size(), 1u);
            at = blob_faces_.size();
            object(0, "blob", 0, t, true);
        }
        // The body's pieces, one object per rigid body of this stage, its fracture faces last.
        for (std::size_t k = 0; k < st.bodies.size(); ++k) {
            const std::uint32_t b = st.bodies[k];
            const io::Transform& t = poses[b];
            const std::size_t first = at;
            for (std::uint32_t p : bodies_[b].pieces) {
                for (std::uint32_t v = piece_vertex_begin_[p]; v < piece_vertex_begin_[p + 1]; ++v) now_[v] = t.apply_point(rest_[v]);
                const std::size_t f0 = piece_face_begin_[p], f1 = piece_face_begin_[p + 1];
                gather_triangles(now_, std::span<const Face>(faces_).subspan(f0, f1 - f0), o + at);
                std::fill_n(m + at, f1 - f0, 2u);
                at += f1 - f0;
            }
            now_[bodies_[b].centre_vertex] = t.apply_point(rest_[bodies_[b].centre_vertex]);
            const std::size_t c0 = st.cap_begin[k], c1 = st.cap_begin[k + 1];
            gather_triangles(now_, std::span<const Face>(st.caps).subspan(c0, c1 - c0), o + at);
            std::fill_n(m + at, c1 - c0, 3u);
            at += c1 - c0;
            object(k + 1, bodies_[b].name, first, t, bodies_[b].moves);
        }
        const std::size_t first = at;
        gather_triangles(floor_.vertices, floor_.faces, o + at);
        std::fill_n(m + at, floor_.faces.size(), 0u);
        at += floor_.faces.size();
        object(st.bodies.size() + 1, "floor", first, io::Transform{}, false);
        out.camera = camera_.at(double(i));
        out.time = double(i) / fps;
    }

    /// Breaking stage shown at frame `i`: 0 intact, 1 broken at the blow, 2 broken again.
    std::size_t state_of_frame(std::size_t i) const noexcept {
        return i < cfg_.impact_frame ? 0 : (i < cfg_.impact_frame + cfg_.second_break ? 1 : 2);
    }

private:
    static constexpr std::uint32_t none = std::numeric_limits<std::uint32_t>::max();
    static constexpr int substeps = 4;

    /// The dragon-like body: a tube round a wavy spine, with per-face (along, around) parameters.
    struct Tube {
        IndexedMesh mesh;
        std::vector<std::array<float, 2>> face_param;   // along in [0, 1], around in [0, 1)
        std::vector<Vec3f> spine;                        // ring centres
        float radius = 1;
        Vec3f spine_at(float s) const {
            const float x = s * float(spine.size() - 1);
            const auto k = std::min<std::size_t>(std::size_t(x), spine.size() - 2);
            const float t = x - float(k);
            return spine[k] * (1 - t) + spine[k + 1] * t;
        }
    };

    struct Body {
        std::string name;
        std::vector<std::uint32_t> pieces;   // finest pieces making it up
        std::uint32_t centre_vertex = 0;     // rest-space centre, apex of its fracture faces
        std::vector<Vec3f> support;          // rest-space extreme points, for floor contact
        std::uint32_t parent = none;         // the body it broke off
        bool moves = false;
    };

    struct State {
        std::vector<std::uint32_t> bodies;   // active bodies other than the blob
        std::vector<Face> caps;              // fracture faces, grouped by body
        std::vector<std::size_t> cap_begin;  // bodies.size() + 1 offsets into caps
    };

    Tube make_body(double triangles, SplitMix64& rng) const {
        Tube t;
        const float r0 = 0.75f;
        t.radius = r0;
        // Quads about square: around / along ~ circumference / length.
        const double ratio = body_length / (2 * std::numbers::pi * r0 * 0.8);
        const auto around = std::max<std::uint32_t>(6, std::uint32_t(std::lround(std::sqrt(triangles / (2 * ratio)))));
        const auto rings = std::max<std::uint32_t>(4, std::uint32_t(std::lround(triangles / (2.0 * around))));
        const float phase = rng.uniformf(0, 6.2831853f), wave = rng.uniformf(0.9f, 1.4f), bend = rng.uniformf(1.2f, 1.8f);
        t.spine.resize(rings);
        std::vector<float> rad(rings);
        for (std::uint32_t k = 0; k < rings; ++k) {
            const float s = float(k) / float(rings - 1);
            t.spine[k] = {(s - 0.5f) * body_length, r0 * (1.1f + 0.5f * std::sin(float(std::numbers::pi) * s * 1.3f)),
                          wave * std::sin(bend * 2 * float(std::numbers::pi) * s + phase)};
            rad[k] = r0 * (0.25f + 0.75f * std::sqrt(std::max(0.0f, std::sin(float(std::numbers::pi) * std::min(1.0f, s * 1.08f)))) +
                           0.45f * std::exp(-(s - 0.9f) * (s - 0.9f) / 0.003f));
        }
        t.mesh.vertices.reserve(std::size_t(rings) * around + 2);
        const Vec3f up{0, 1, 0};
        for (std::uint32_t k = 0; k < rings; ++k) {
            const Vec3f tan = normalize(t.spine[std::min(k + 1, rings - 1)] - t.spine[k > 0 ? k - 1 : 0]);
            const Vec3f n = normalize(up - tan * dot(up, tan)), b = cross(tan, n);
            const float s = float(k) / float(rings - 1);
            const float spikes = std::pow(0.5f + 0.5f * std::cos(2 * float(std::numbers::pi) * 30 * s), 3.0f);
            for (std::uint32_t j = 0; j < around; ++j) {
                const float th = 2 * float(std::numbers::pi) * float(j) / float(around);
                const float back = std::max(0.0f, std::cos(th));
                const float r = rad[k] * (1 + 0.45f * spikes * std::pow(back, 8.0f) + 0.04f * std::sin(7 * th + 40 * s));
                t.mesh.vertices.push_back(t.spine[k] + (n * std::cos(th) + b * std::sin(th)) * r);
            }
        }
        const auto tail = std::uint32_t(t.mesh.vertices.size());
        t.mesh.vertices.push_back(t.spine.front() - normalize(t.spine[1] - t.spine[0]) * (0.3f * r0));
        t.mesh.vertices.push_back(t.spine.back() + normalize(t.spine[rings - 1] - t.spine[rings - 2]) * (0.4f * r0));
        auto at = [&](std::uint32_t k, std::uint32_t j) { return k * around + j % around; };
        for (std::uint32_t k = 0; k + 1 < rings; ++k)
            for (std::uint32_t j = 0; j < around; ++j) {
                const std::uint32_t a = at(k, j), b = at(k, j + 1), c = at(k + 1, j), d = at(k + 1, j + 1);
                const std::array<float, 2> prm{(float(k) + 0.5f) / float(rings - 1), (float(j) + 0.5f) / float(around)};
                t.mesh.faces.push_back({a, b, d});
                t.mesh.faces.push_back({a, d, c});
                t.face_param.push_back(prm);
                t.face_param.push_back(prm);
            }
        for (std::uint32_t j = 0; j < around; ++j) {
            const float v = (float(j) + 0.5f) / float(around);
            t.mesh.faces.push_back({tail, at(0, j + 1), at(0, j)});
            t.face_param.push_back({0, v});
            t.mesh.faces.push_back({tail + 1, at(rings - 1, j), at(rings - 1, j + 1)});
            t.face_param.push_back({1, v});
        }
        // Rest on the floor.
        float low = std::numeric_limits<float>::infinity();
        for (const Vec3f& v : t.mesh.vertices) low = std::min(low, v.y);
        for (Vec3f& v : t.mesh.vertices) v.y -= low;
        for (Vec3f& v : t.spine) v.y -= low;
        return t;
    }

    /// The bunny-like blob: an ellipsoid with random smooth bumps, a head and two ears.
    static IndexedMesh make_blob(double triangles, SplitMix64& rng) {
        const SphereResolution sr = sphere_resolution(triangles);
        IndexedMesh m = uv_sphere({0, 0, 0}, 1, sr.slices, sr.stacks);
        struct Bump { Vec3f dir; float kappa, amp; };
        std::vector<Bump> bumps;
        for (int k = 0; k < 10; ++k) bumps.push_back({rng.unit_vector(), rng.uniformf(3, 9), rng.uniformf(-0.07f, 0.09f)});
        const float yaw = rng.uniformf(0, 6.2831853f);
        const Vec3f fwd{std::cos(yaw), 0, std::sin(yaw)}, side{-std::sin(yaw), 0, std::cos(yaw)};
        bumps.push_back({normalize(fwd * 0.8f + Vec3f{0, 0.6f, 0}), 10, 0.35f});                     // head
        bumps.push_back({normalize(fwd * 0.45f + side * 0.22f + Vec3f{0, 1, 0}), 60, 0.75f});        // ears
        bumps.push_back({normalize(fwd * 0.45f - side * 0.22f + Vec3f{0, 1, 0}), 60, 0.7f});
        const float radius = 1.6f;
        for (Vec3f& v : m.vertices) {
            const Vec3f d = normalize(v);
            float r = 1;
            for (const Bump& b : bumps) r += b.amp * std::exp(b.kappa * (dot(d, b.dir) - 1));
            v = Vec3f{d.x * 1.1f, d.y * 0.9f, d.z * 0.95f} * (radius * r);
        }
        return m;
    }

    /// Nearest jittered seed of a periodic-in-v grid of cells: Voronoi cell id of (u, v) in cell units.
    static std::uint32_t voronoi(float u, float v, std::uint32_t nu, std::uint32_t nv, std::uint64_t seed) noexcept {
        const auto iu = std::int64_t(std::floor(u)), iv = std::int64_t(std::floor(v));
        float best = std::numeric_limits<float>::infinity();
        std::uint32_t id = 0;
        for (std::int64_t du = -1; du <= 1; ++du)
            for (std::int64_t dv = -1; dv <= 1; ++dv) {
                const std::int64_t cu = iu + du, cv = iv + dv;
                if (cu < 0 || cu >= std::int64_t(nu)) continue;
                const auto wv = std::uint32_t(((cv % std::int64_t(nv)) + std::int64_t(nv)) % std::int64_t(nv));
                const float su = float(cu) + 0.15f + 0.7f * hash01(seed, std::uint64_t(cu), wv);
                const float sv = float(cv) + 0.15f + 0.7f * hash01(seed ^ 0x5555u, std::uint64_t(cu), wv);
                const float d = (u - su) * (u - su) + (v - sv) * (v - sv);
                if (d < best) { best = d; id = std::uint32_t(cu) * nv + wv; }
            }
        return id;
    }

    /// Sorts the body's faces into finest pieces (coarse cell x fine cell), gives each piece its
    /// own vertex copies, and records every face's neighbours across its edges.
    void build_pieces(const Tube& body, SplitMix64& rng) {
        const std::uint64_t coarse_seed = rng.next(), fine_seed = rng.next();
        const std::uint32_t nu = cfg_.cells_along, nv = cfg_.cells_around, fu = nu * cfg_.split, fv = nv * cfg_.split;
        const std::size_t nf = body.mesh.faces.size();
        std::vector<std::uint64_t> key(nf);
        for (std::size_t f = 0; f < nf; ++f) {
            const auto& p = body.face_param[f];
            const std::uint64_t c = voronoi(p[0] * float(nu), p[1] * float(nv), nu, nv, coarse_seed);
            const std::uint64_t q = voronoi(p[0] * float(fu), p[1] * float(fv), fu, fv, fine_seed);
            key[f] = ((c * fu * fv + q) << 32) | f;   // face index last: a stable, total order
        }
        std::sort(key.begin(), key.end());
        std::vector<std::uint32_t> slot(nf);   // original face -> position in faces_
        std::vector<std::uint32_t> stamp(body.mesh.vertices.size(), none), local(body.mesh.vertices.size());
        piece_face_begin_.clear();
        piece_vertex_begin_.clear();
        piece_coarse_.clear();
        rest_.clear();
        faces_.clear();
        faces_.reserve(nf);
        std::uint64_t prev_key = std::numeric_limits<std::uint64_t>::max();
        for (std::size_t i = 0; i < nf; ++i) {
            const std::uint64_t k = key[i] >> 32;
            const auto f = std::uint32_t(key[i] & 0xffffffffu);
            if (k != prev_key) {
                prev_key = k;
                piece_face_begin_.push_back(std::uint32_t(i));
                piece_vertex_begin_.push_back(std::uint32_t(rest_.size()));
                piece_coarse_.push_back(std::uint32_t(k / (std::uint64_t(fu) * fv)));
            }
            const auto piece = std::uint32_t(piece_face_begin_.size() - 1);
            Face out{};
            for (int c = 0; c < 3; ++c) {
                const std::uint32_t v = body.mesh.faces[f][c];
                if (stamp[v] != piece) {
                    stamp[v] = piece;
                    local[v] = std::uint32_t(rest_.size());
                    rest_.push_back(body.mesh.vertices[v]);
                }
                out[c] = local[v];
            }
            faces_.push_back(out);
            slot[f] = std::uint32_t(i);
        }
        piece_face_begin_.push_back(std::uint32_t(nf));
        piece_vertex_begin_.push_back(std::uint32_t(rest_.size()));
        face_piece_.resize(nf);
        for (std::uint32_t p = 0; p + 1 < piece_face_begin_.size(); ++p)
            std::fill(face_piece_.begin() + piece_face_begin_[p], face_piece_.begin() + piece_face_begin_[p + 1], p);

        // Edge neighbours through a vertex -> faces table of the original (shared-vertex) mesh.
        const std::size_t nvtx = body.mesh.vertices.size();
        std::vector<std::uint32_t> start(nvtx + 1, 0), incident(3 * nf);
        for (const Face& f : body.mesh.faces)
            for (std::uint32_t v : f) ++start[v + 1];
        std::partial_sum(start.begin(), start.end(), start.begin());
        std::vector<std::uint32_t> fill(start.begin(), start.end() - 1);
        for (std::uint32_t f = 0; f < nf; ++f)
            for (std::uint32_t v : body.mesh.faces[f]) incident[fill[v]++] = f;
        neighbour_.assign(3 * nf, none);
        for (std::uint32_t f = 0; f < nf; ++f)
            for (int e = 0; e < 3; ++e) {
                const std::uint32_t a = body.mesh.faces[f][e], b = body.mesh.faces[f][(e + 1) % 3];
                for (std::uint32_t k = start[a]; k < start[a + 1]; ++k) {
                    const std::uint32_t g = incident[k];
                    if (g == f) continue;
                    const Face& h = body.mesh.faces[g];
                    if ((h[0] == b && h[1] == a) || (h[1] == b && h[2] == a) || (h[2] == b && h[0] == a)) {
                        neighbour_[3 * std::size_t(slot[f]) + std::size_t(e)] = slot[g];
                        break;
                    }
                }
            }
    }

    /// Centre of a set of pieces' rest vertices.
    Vec3f pieces_centre(const std::vector<std::uint32_t>& pieces) const {
        Vec3d c{0, 0, 0};
        std::size_t n = 0;
        for (std::uint32_t p : pieces)
            for (std::uint32_t v = piece_vertex_begin_[p]; v < piece_vertex_begin_[p + 1]; ++v, ++n) c += Vec3d(rest_[v]);
        return n ? Vec3f(c * (1.0 / double(n))) : Vec3f{0, 0, 0};
    }

    std::uint32_t add_body(std::string name, std::vector<std::uint32_t> pieces, std::uint32_t parent, bool moves) {
        Body b;
        b.name = std::move(name);
        b.pieces = std::move(pieces);
        b.parent = parent;
        b.moves = moves;
        b.centre_vertex = std::uint32_t(rest_.size());
        const Vec3f c = pieces_centre(b.pieces);
        rest_.push_back(c);
        // Extreme points along 13 directions (axes, face and edge diagonals) for floor contact.
        static constexpr std::array<std::array<float, 3>, 13> dirs = {{{1, 0, 0}, {0, 1, 0}, {0, 0, 1}, {1, 1, 1}, {1, 1, -1}, {1, -1, 1}, {-1, 1, 1},
                                                                         {1, 1, 0}, {1, -1, 0}, {1, 0, 1}, {1, 0, -1}, {0, 1, 1}, {0, 1, -1}}};
        for (const auto& d3 : dirs) {
            const Vec3f d{d3[0], d3[1], d3[2]};
            float lo = std::numeric_limits<float>::infinity(), hi = -lo;
            Vec3f plo = c, phi = c;
            for (std::uint32_t p : b.pieces)
                for (std::uint32_t v = piece_vertex_begin_[p]; v < piece_vertex_begin_[p + 1]; ++v) {
                    const float s = dot(rest_[v], d);
                    if (s < lo) { lo = s; plo = rest_[v]; }
                    if (s > hi) { hi = s; phi = rest_[v]; }
                }
            b.support.push_back(plo);
            b.support.push_back(phi);
        }
        bodies_.push_back(std::move(b));
        return std::uint32_t(bodies_.size() - 1);
    }

    /// Bodies of the three stages and their fracture faces.
    void build_states() {
        const std::size_t np = piece_coarse_.size();
        // Group pieces by coarse cell (pieces are sorted by coarse cell already).
        std::vector<std::vector<std::uint32_t>> cells;
        std::vector<std::uint32_t> cell_of_piece(np);
        for (std::uint32_t p = 0; p < np; ++p) {
            if (p == 0 || piece_coarse_[p] != piece_coarse_[p - 1]) cells.emplace_back();
            cells.back().push_back(p);
            cell_of_piece[p] = std::uint32_t(cells.size() - 1);
        }
        bodies_.clear();
        bodies_.push_back({});   // 0: the blob, filled in by add_blob
        std::vector<std::uint32_t> all(np);
        std::iota(all.begin(), all.end(), 0u);
        const std::uint32_t whole = add_body("body", all, none, false);

        const float r1 = cfg_.broken_radius * body_length, r2 = cfg_.fine_radius * body_length;
        std::vector<float> cell_dist(cells.size());
        std::vector<Vec3f> cell_centre(cells.size());
        for (std::size_t c = 0; c < cells.size(); ++c) {
            cell_centre[c] = pieces_centre(cells[c]);
            cell_dist[c] = length(cell_centre[c] - impact_);
        }
        // Stage 1: cells near the blow become shards; the rest stays in two remnants (either side of the blow).
        std::vector<std::uint32_t> tail, head;
        std::vector<std::uint32_t> stage1(np), stage2(np);
        std::vector<std::uint32_t> shard_of_cell(cells.size(), none);
        std::vector<std::uint32_t> stage1_bodies;
        for (std::size_t c = 0; c < cells.size(); ++c) {
            if (cell_dist[c] < r1) {
                shard_of_cell[c] = add_body("shard" + std::to_string(c), cells[c], whole, true);
                stage1_bodies.push_back(shard_of_cell[c]);
            } else {
                auto& side = cell_centre[c].x < impact_.x ? tail : head;   // the body runs along x
                side.insert(side.end(), cells[c].begin(), cells[c].end());
            }
        }
        std::uint32_t tail_body = none, head_body = none;
        if (!tail.empty()) stage1_bodies.push_back(tail_body = add_body("remnant0", tail, whole, false));
        if (!head.empty()) stage1_bodies.push_back(head_body = add_body("remnant1", head, whole, false));
        for (std::uint32_t b : stage1_bodies)
            for (std::uint32_t p : bodies_[b].pieces) stage1[p] = b;
        // Stage 2: shards near the blow break into their finest pieces.
        std::vector<std::uint32_t> stage2_bodies;
        for (std::uint32_t b : stage1_bodies) {
            const std::uint32_t c = bodies_[b].pieces.empty() ? 0 : cell_of_piece[bodies_[b].pieces[0]];
            if (b != tail_body && b != head_body && cell_dist[c] < r2 && bodies_[b].pieces.size() > 1) {
                const std::vector<std::uint32_t> pieces = bodies_[b].pieces;
                for (std::uint32_t p : pieces) stage2_bodies.push_back(add_body("chip" + std::to_string(p), {p}, b, true));
            } else {
                stage2_bodies.push_back(b);
            }
        }
        for (std::uint32_t b : stage2_bodies)
            for (std::uint32_t p : bodies_[b].pieces) stage2[p] = b;

        states_.assign(3, {});
        states_[0].bodies = {whole};
        states_[1].bodies = stage1_bodies;
        states_[2].bodies = stage2_bodies;
        const std::vector<std::uint32_t> stage0(np, whole);
        const std::array<const std::vector<std::uint32_t>*, 3> body_of = {&stage0, &stage1, &stage2};
        for (std::size_t s = 0; s < 3; ++s) {
            State& st = states_[s];
            const auto& owner = *body_of[s];
            st.cap_begin.push_back(0);
            for (std::uint32_t b : st.bodies) {
                for (std::uint32_t p : bodies_[b].pieces)
                    for (std::uint32_t f = piece_face_begin_[p]; f < piece_face_begin_[p + 1]; ++f)
                        for (int e = 0; e < 3; ++e) {
                            const std::uint32_t g = neighbour_[3 * std::size_t(f) + std::size_t(e)];
                            if (g == none || owner[face_piece_[g]] == b) continue;
                            // Close the crack: a fan from the edge to the body's centre, wound to face outwards.
                            st.caps.push_back({faces_[f][(e + 1) % 3], faces_[f][e], bodies_[b].centre_vertex});
                        }
                st.cap_begin.push_back(st.caps.size());
            }
        }
        neighbour_ = {};
        face_piece_ = {};
    }

    void add_blob(const IndexedMesh& blob) {
        blob_vertex_begin_ = std::uint32_t(rest_.size());
        for (const Vec3f& v : blob.vertices) rest_.push_back(v);
        blob_vertex_end_ = std::uint32_t(rest_.size());
        blob_faces_.clear();
        for (const Face& f : blob.faces) blob_faces_.push_back({f[0] + blob_vertex_begin_, f[1] + blob_vertex_begin_, f[2] + blob_vertex_begin_});
        Body& b = bodies_[0];
        b.name = "blob";
        b.moves = true;
        b.centre_vertex = blob_vertex_begin_;
        float low = 0;
        for (const Vec3f& v : blob.vertices) low = std::min(low, v.y);
        blob_bottom_ = -low;
        for (const Vec3f& v : blob.vertices)
            if (v.y < 0.5f * low) b.support.push_back(v);
        // Keep the lowest points only, a few dozen: enough for contact.
        std::sort(b.support.begin(), b.support.end(), [](const Vec3f& a, const Vec3f& c) { return a.y < c.y || (a.y == c.y && a.x < c.x); });
        if (b.support.size() > 48) {
            std::vector<Vec3f> keep;
            for (std::size_t k = 0; k < 48; ++k) keep.push_back(b.support[k * b.support.size() / 48]);
            b.support = keep;
        }
        now_.resize(rest_.size());
    }

    struct BodyMotion {
        Pose pose;
        Vec3f v{0, 0, 0}, w{0, 0, 0};
        bool active = false;
    };

    void integrate(BodyMotion& m, const Body& b, float dt, float restitution) const {
        m.v.y -= cfg_.gravity * dt;
        m.pose.position += m.v * dt;
        m.pose.rotation = m.pose.rotation.integrate(m.w, dt);
        const io::Transform t = m.pose.transform();
        float low = std::numeric_limits<float>::infinity();
        for (const Vec3f& s : b.support) low = std::min(low, t.apply_point(s).y);
        if (low < 0) {
            m.pose.position.y -= low;
            if (m.v.y < 0) m.v.y = -restitution * m.v.y;
            m.v.x *= 0.8f;
            m.v.z *= 0.8f;
            m.w = m.w * 0.8f;
        }
    }

    void simulate(SplitMix64& rng) {
        const std::size_t nb = bodies_.size(), nfr = cfg_.frames;
        std::vector<BodyMotion> mo(nb);
        for (std::size_t b = 1; b < nb; ++b) {
            const Vec3f c = rest_[bodies_[b].centre_vertex];
            mo[b].pose = {Quat{}, c, c};
        }
        // The blob falls to touch the body's back at the impact frame.
        const float t1 = float(cfg_.impact_frame), g = cfg_.gravity;
        const float fall_speed = 0.35f * g * t1;   // downward speed at frame 0
        const Vec3f blob_hit{impact_.x, impact_.y + blob_bottom_, impact_.z};
        BodyMotion& blob = mo[0];
        blob.pose = {Quat{}, {0, 0, 0}, blob_hit + Vec3f{0, fall_speed * t1 + 0.5f * g * t1 * t1, 0}};
        blob.v = {0, -fall_speed, 0};
        blob.active = true;
        poses_.assign(nfr * nb, io::Transform{});
        const float dt = 1.0f / substeps;
        for (std::size_t f = 0; f < nfr; ++f) {
            if (f == cfg_.impact_frame) {
                const float hit = length(blob.v);
                for (std::uint32_t b : states_[1].bodies) {
                    BodyMotion& m = mo[b];
                    m.active = true;
                    if (!bodies_[b].moves) continue;
                    const Vec3f c = rest_[bodies_[b].centre_vertex], d = c - impact_;
                    const float dh = std::sqrt(d.x * d.x + d.z * d.z), dist = length(d);
                    const Vec3f dir = normalize(Vec3f{d.x, std::max(d.y, 0.0f) + 0.5f * dh, d.z} + rng.unit_vector() * 0.2f);
                    const float falloff = std::max(0.0f, 1 - dist / (cfg_.broken_radius * body_length));
                    m.v = dir * (cfg_.shard_speed * hit * (0.15f + 0.75f * falloff) * rng.uniformf(0.7f, 1.3f));
                    m.w = rng.unit_vector() * (hit * falloff * rng.uniformf(0.2f, 0.6f));
                }
                blob.v = blob.v * 0.3f;
                blob.w = rng.unit_vector() * 0.02f;
            }
            if (f == cfg_.impact_frame + cfg_.second_break) {
                for (std::uint32_t b : states_[2].bodies) {
                    BodyMotion& m = mo[b];
                    if (m.active) continue;
                    const BodyMotion& parent = mo[bodies_[b].parent];
                    const Vec3f rc = rest_[bodies_[b].centre_vertex];
                    const io::Transform pt = parent.pose.transform();
                    m.pose = {parent.pose.rotation, rc, pt.apply_point(rc)};
                    const Vec3f arm = m.pose.position - parent.pose.position;
                    const Vec3f away = length(arm) > 1e-6f ? normalize(arm) : rng.unit_vector();
                    m.v = parent.v + cross(parent.w, arm) + away * (0.25f * length(parent.v) + 0.02f) + rng.unit_vector() * 0.02f;
                    m.w = parent.w + rng.unit_vector() * rng.uniformf(0.02f, 0.15f);
                    m.active = true;
                }
            }
            for (std::size_t b = 0; b < nb; ++b) poses_[f * nb + b] = mo[b].pose.transform();
            for (int s = 0; s < substeps; ++s)
                for (std::size_t b = 0; b < nb; ++b)
                    if (mo[b].active && bodies_[b].moves) integrate(mo[b], bodies_[b], dt, b == 0 ? 0.15f : 0.3f);
        }
    }

    void describe(SplitMix64& rng) {
        info_.name = std::string(cfg_.name);
        info_.motion = io::Motion::semi_hierarchical;
        info_.topology_changes = true;
        info_.frames = cfg_.frames;
        info_.materials = {io::Material{.name = "floor", .diffuse = {0.5f, 0.5f, 0.5f}},
                           io::Material{.name = "blob", .diffuse = {0.8f, 0.7f, 0.55f}},
                           io::Material{.name = "body", .diffuse = {0.25f, 0.55f, 0.35f}},
                           io::Material{.name = "fracture", .diffuse = {0.65f, 0.8f, 0.6f}}};
        info_.lights = {io::Light{.position = {6, 18, 10}, .color = {1, 1, 1}}};
        camera_.target = {0, 2.2f, 0};
        camera_.distance = OrbitCamera::framing_distance(0.62f * body_length, camera_.fov_y_deg);
        camera_.elevation = 0.45f;
        camera_.start_angle = rng.uniformf(0.9f, 2.2f);
        camera_.angular_speed = 0.3f / float(cfg_.frames);
    }

    BreakingConfig cfg_;
    io::SceneInfo info_;
    OrbitCamera camera_;
    Vec3f impact_{0, 0, 0};
    float blob_bottom_ = 0;
    std::vector<Vec3f> rest_, now_;                 // every vertex at rest / in the current frame
    std::vector<Face> faces_;                       // the body's faces, grouped by finest piece
    std::vector<std::uint32_t> piece_face_begin_, piece_vertex_begin_, piece_coarse_;
    std::vector<std::uint32_t> neighbour_, face_piece_;   // construction only
    std::vector<Body> bodies_;                      // 0 is the blob
    std::vector<State> states_;
    std::vector<Face> blob_faces_;
    std::uint32_t blob_vertex_begin_ = 0, blob_vertex_end_ = 0;
    IndexedMesh floor_;
    std::vector<io::Transform> poses_;              // frames x bodies
};

} // namespace dynbvh::scenes
