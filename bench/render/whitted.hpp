/// @file render/whitted.hpp
/// A small Whitted-style ray tracer (Whitted 1980, "An improved illumination model for shaded
/// display") on top of any closest-hit / any-hit tracer: our `Bvh` (`BvhTracer`), Embree
/// (bench/embree_bvh.hpp's EmbreeBvh satisfies `Tracer` as it is) or the study's `Accel`.
/// Not part of the library: it lives in bench/ to measure what secondary effects cost per builder.
///
/// Only the effects a scene calls for are traced:
///  - shadow rays (any hit) from a shaded point towards each light of the scene that lies on the
///    side of the surface the ray came from, when the material's diffuse or Phong term is non-zero;
///    no lights, no shadow rays. Every triangle occludes (glass casts full shadows, as in Whitted's
///    model with opaque shadow tests);
///  - reflection rays from materials with `specular > 0` (mirror weight = specular) and from
///    dielectrics (`transmission > 0`) for their Fresnel share of the transmitted part
///    (`transmission * F`; all of it under total internal reflection): a scene whose materials have
///    neither specular nor transmission traces no reflection ray;
///  - refraction rays from materials with `transmission > 0`, weight `transmission * (1 - F)`:
///    Snell's law, the exact unpolarised dielectric Fresnel reflectance F = (r_s^2 + r_p^2) / 2
///    (not Schlick's approximation), total internal reflection when sin(theta_t) > 1. Entering or
///    leaving is decided by the side of the triangle's geometric normal (p1 - p0) x (p2 - p0) the
///    ray arrives from: closed glass meshes must be wound counter-clockwise seen from outside
///    (outward normals), as OBJ and BART expect. Leaving = into a medium of index 1.
/// A path stops at `Config::max_depth` secondary bounces, or when its weight (largest channel of
/// the product of the reflection/refraction weights along it) falls below `Config::min_weight`.
///
/// Shading (linear RGB): ambient `Config::ambient * diffuse`, plus per visible light
/// `light.color * (diffuse * n.l + specular * max(0, r.v)^shininess)` (no distance falloff, as in NFF
/// and BART), plus the weighted reflection and refraction. Misses see the background. Flat
/// shading: normals are the triangles' geometric normals (Frame carries no vertex normals).
///
/// Secondary origins: the hit point is rebuilt from the barycentrics (p0 + u e1 + v e2, accurate to
/// a few ulps of the triangle's coordinates, unlike org + t dir), then moved off the surface along
/// the geometric normal, towards the side the new ray leaves to, by
/// `Config::offset * max |coordinate of the triangle's vertices|`: a scale-aware epsilon, so the
/// same setting works for scenes in millimetres or kilometres. Rays then start at t = 0.
///
/// Execution is a wavefront per batch of 16x16 pixel tiles: all primary rays of the batch are traced,
/// the hits are shaded (which queues shadow, reflection and refraction rays), each queue is traced
/// on its own, and so on per depth. Each kind is traced in its own timed pass, so `Stats` has exact
/// ray counts and trace time per kind; shading and queue handling are timed apart (`shade_ms`). Work
/// is spread over the executor's `for_tasks` in chunks of consecutive rays (neighbouring pixels
/// first, so secondary rays stay as coherent as the scene lets them). Results do not depend on the
/// executor or thread count: queues are merged and pixels accumulated in a fixed order.
///
/// Packets: a `PacketTracer` (one that also answers up to 16 rays at once, with the answers of 16
/// single rays) traces primary rays 16 at a time (16 consecutive pixels of a tile row;
/// `Config::packets`), and shadow rays too with `Config::shadow_packets` (off by default: their
/// origins spread over the visible surface, and our packet traversal measured slower on them than
/// single rays); reflection and refraction rays, which scatter, go one at a time. The image and
/// counts are the same either way.
#pragma once

#include <algorithm>
#include <array>
#include <chrono>
#include <cmath>
#include <concepts>
#include <cstddef>
#include <cstdint>
#include <optional>
#include <span>
#include <vector>

#include <dynbvh/io/bart.hpp>
#include <dynbvh/io/scene.hpp>
#include <dynbvh/packet.hpp>
#include <dynbvh/ray.hpp>
#include <dynbvh/traverse.hpp>

#include "material.hpp"

namespace dynbvh::render {

/// Something that answers one ray at a time: the closest hit (t, u, v, triangle index into the
/// scene's triangle array; `prim == invalid_prim` for a miss) and whether anything is hit at all.
template <class T>
concept Tracer = requires(const T& t, const Rayf& r) {
    { t.intersect(r) } -> std::convertible_to<Hitf>;
    { t.occluded(r) } -> std::convertible_to<bool>;
};

/// A Tracer that also answers rays.size() <= 16 rays at once: out[k] = intersect(rays[k]), resp.
/// blocked[k] = occluded(rays[k]) (ray packets, e.g. dynbvh's packet.hpp or Embree's rtcIntersect16).
template <class T>
concept PacketTracer = Tracer<T> && requires(const T& t, std::span<const Rayf> r, std::span<Hitf> h, std::span<std::uint8_t> b) {
    t.intersect_packet(r, h);
    t.occluded_packet(r, b);
};

/// The first 16 of `rays` in lanes 0.. of `p` (the other lanes keep default rays); returns the mask
/// of the lanes set.
inline std::uint32_t ray_packet16(std::span<const Rayf> rays, RayPacket<float, 16>& p) {
    const std::size_t n = std::min<std::size_t>(16, rays.size());
    for (std::size_t k = 0; k < n; ++k) p.set(int(k), rays[k]);
    return n >= 16 ? 0xffffu : (1u << n) - 1u;
}

/// Up to 16 rays through one of our wide trees (`tree`, any wide or block tree) as one packet of
/// packet.hpp: out[k] (resp. blocked[k]) = the single-ray answer for rays[k], bit for bit.
template <class Policy, class Tree>
void intersect_packet(const Tree& tree, std::span<const Trianglef> tris, std::span<const Rayf> rays, std::span<Hitf> out) {
    RayPacket<float, 16> p;
    const HitPacket<float, 16> h = dynbvh::intersect<Policy>(tree, tris, p, ray_packet16(rays, p));
    for (std::size_t k = 0; k < std::min<std::size_t>(16, rays.size()); ++k) out[k] = h.hit(int(k));
}
/// See intersect_packet.
template <class Policy, class Tree>
void occluded_packet(const Tree& tree, std::span<const Trianglef> tris, std::span<const Rayf> rays, std::span<std::uint8_t> blocked) {
    RayPacket<float, 16> p;
    const std::uint32_t m = dynbvh::occluded<Policy>(tree, tris, p, ray_packet16(rays, p));
    for (std::size_t k = 0; k < std::min<std::size_t>(16, rays.size()); ++k) blocked[k] = (m >> k) & 1u;
}

/// Primary rays: width() x height() pixels, ray(x, y) through pixel (x, y), row 0 at the top
/// (the study's RayGen is one).
template <class C>
concept Camera = requires(const C& c, int x, int y) {
    { c.width() } -> std::convertible_to<int>;
    { c.height() } -> std::convertible_to<int>;
    { c.ray(x, y) } -> std::convertible_to<Rayf>;
};

/// Executor: `for_tasks(n, f)` runs f(0) .. f(n - 1), possibly at once (dynbvh::exec::*, study::Backend).
template <class E>
concept TaskExecutor = requires(const E& e, void (*f)(std::size_t)) { e.for_tasks(std::size_t{1}, f); };

/// One of our BVHs over `tris` as a Tracer, traced with `Policy` (dynbvh::trace::robust by default).
template <class Policy, class BvhT>
struct BvhTracer {
    const BvhT& bvh;
    std::span<const Trianglef> tris;
    Hitf intersect(const Rayf& r) const { return dynbvh::intersect<Policy>(bvh, tris, r); }
    bool occluded(const Rayf& r) const { return dynbvh::occluded<Policy>(bvh, tris, r); }
    /// Wide trees only (packet.hpp): a PacketTracer.
    void intersect_packet(std::span<const Rayf> r, std::span<Hitf> out) const requires requires { BvhT::node_type::width; }
    {
        render::intersect_packet<Policy>(bvh, tris, r, out);
    }
    void occluded_packet(std::span<const Rayf> r, std::span<std::uint8_t> out) const requires requires { BvhT::node_type::width; }
    {
        render::occluded_packet<Policy>(bvh, tris, r, out);
    }
};

/// `render(bvh_tracer(bvh, tris), ...)`.
template <class Policy = trace::robust, class BvhT>
BvhTracer<Policy, BvhT> bvh_tracer(const BvhT& bvh, std::span<const Trianglef> tris) {
    return {bvh, tris};
}

/// The four kinds of rays, in the order of `Stats`' arrays.
enum class RayKind : int { primary = 0, shadow = 1, reflection = 2, refraction = 3 };
inline constexpr int ray_kind_count = 4;
inline constexpr std::array<RayKind, 4> ray_kinds{RayKind::primary, RayKind::shadow, RayKind::reflection, RayKind::refraction};

inline const char* to_string(RayKind k) noexcept {
    switch (k) {
        case RayKind::primary: return "primary";
        case RayKind::shadow: return "shadow";
        case RayKind::reflection: return "reflection";
        case RayKind::refraction: return "refraction";
    }
    return "?";
}

/// Knobs of the renderer (designated-initialiser friendly: `{.max_depth = 3}`).
struct Config {
    int max_depth = 5;                       ///< most reflection/refraction bounces along a path (primary = depth 0)
    float min_weight = 1e-3f;                ///< secondary and shadow rays contributing less (largest channel) are not traced
    float offset = 1e-5f;                    ///< origin offset along the normal, relative to the triangle's largest |coordinate|
    Vec3f ambient{0.1f, 0.1f, 0.1f};         ///< ambient light; adds ambient * diffuse at every hit
    float headlight = 0.6f;                  ///< scenes without lights only: diffuse * headlight * |n.d| (a light at the eye, no shadow rays)
    Vec3f background{0.05f, 0.07f, 0.12f};   ///< what a ray that hits nothing sees
    bool shadows = true;                     ///< trace shadow rays where lights call for them (false: lights ignored)
    bool reflections = true;                 ///< trace reflection rays where materials call for them
    bool refractions = true;                 ///< trace refraction rays where materials call for them
    std::size_t batch_rays = std::size_t(1) << 16;   ///< primary rays per wavefront batch (bounds the queues' memory)
    std::size_t chunk_rays = 256;            ///< consecutive rays per task
    bool packets = true;                     ///< primary rays 16 at a time through a PacketTracer
    bool shadow_packets = false;             ///< shadow rays 16 at a time through a PacketTracer
};

/// Ray counts and times of one render, per RayKind (index with `int(kind)`).
struct Stats {
    std::array<std::uint64_t, 4> rays{};     ///< rays traced per kind
    std::array<double, 4> trace_ms{};        ///< wall time of the tracing passes per kind
    double shade_ms = 0;                     ///< everything else: ray generation, shading, queues, accumulation
    int depth_reached = 0;                   ///< deepest bounce traced (0: primary rays only)

    std::uint64_t count(RayKind k) const noexcept { return rays[std::size_t(k)]; }
    double ms(RayKind k) const noexcept { return trace_ms[std::size_t(k)]; }
    std::uint64_t total_rays() const noexcept { return rays[0] + rays[1] + rays[2] + rays[3]; }
    double total_trace_ms() const noexcept { return trace_ms[0] + trace_ms[1] + trace_ms[2] + trace_ms[3]; }
    Stats& operator+=(const Stats& o) noexcept {
        for (std::size_t k = 0; k < 4; ++k) {
            rays[k] += o.rays[k];
            trace_ms[k] += o.trace_ms[k];
        }
        shade_ms += o.shade_ms;
        depth_reached = std::max(depth_reached, o.depth_reached);
        return *this;
    }
};

/// Linear RGB, row 0 at the top: pixels[y * width + x].
struct Image {
    int width = 0, height = 0;
    std::vector<Vec3f> pixels;
};

/// What the renderer reads of a scene: triangles, one material id per triangle (empty: material 0
/// everywhere), the materials (empty, or an id out of range: the default io::Material) and lights;
/// optionally the scene's own background colour (BART `b`).
struct SceneView {
    std::span<const Trianglef> triangles;
    std::span<const std::uint32_t> material;
    std::span<const io::Material> materials;
    std::span<const io::Light> lights;
    std::optional<Vec3f> background;   ///< set: replaces Config::background
};

/// A frame of a scene as a SceneView (materials and lights from the scene's info).
inline SceneView scene_view(const io::Frame& f, const io::SceneInfo& info) {
    return {f.triangles, f.material, info.materials, info.lights, std::nullopt};
}

/// As above, plus the background of a BART scene. (BART's global ambient `am` is not used: its scale
/// belongs to the reference renderer's model; the ambient term is always Config::ambient * diffuse.)
inline SceneView scene_view(const io::Frame& f, const io::Scene& scene) {
    SceneView v = scene_view(f, scene.info());
    if (const auto* bart = dynamic_cast<const io::BartScene*>(&scene)) v.background = bart->background();
    return v;
}

/// Which effects `scene` calls for: any light (shadows), any material with specular > 0 or
/// transmission > 0 (reflection), any with transmission > 0 (refraction). Materials no triangle
/// uses count too (the renderer itself only traces what the hit materials ask for).
struct Needs {
    bool shadows = false, reflections = false, refractions = false;
};
inline Needs scene_needs(std::span<const io::Material> materials, std::span<const io::Light> lights) {
    Needs n;
    n.shadows = !lights.empty();
    for (const io::Material& m : materials) {
        n.reflections = n.reflections || reflects(m) || refracts(m);
        n.refractions = n.refractions || refracts(m);
    }
    return n;
}

// ---- optics (unit vectors) ---------------------------------------------------------------------

/// Mirror direction of `d` about the unit normal `n`.
inline Vec3f reflect(const Vec3f& d, const Vec3f& n) noexcept { return d - n * (2 * dot(d, n)); }

/// Exact Fresnel reflectance of unpolarised light at a smooth dielectric interface, from the cosines
/// of the incident and transmitted angles and eta = n1 / n2 (incident over transmitted index).
inline float fresnel_dielectric(float cos_i, float cos_t, float eta) noexcept {
    const float rs = (eta * cos_i - cos_t) / (eta * cos_i + cos_t);
    const float rp = (cos_i - eta * cos_t) / (cos_i + eta * cos_t);
    return 0.5f * (rs * rs + rp * rp);
}

/// Result of `refract`: the transmitted direction (unit) and the Fresnel reflectance; under total
/// internal reflection `total_internal` is set, `fresnel` is 1 and `dir` is unused.
struct Refraction {
    bool total_internal = false;
    Vec3f dir{};
    float fresnel = 1;
};

/// Snell's law for the unit direction `d` arriving at a surface with unit normal `n` facing the
/// incoming ray (dot(d, n) <= 0), eta = n1 / n2.
inline Refraction refract(const Vec3f& d, const Vec3f& n, float eta) noexcept {
    Refraction r;
    const float cos_i = std::min(1.0f, std::max(0.0f, -dot(d, n)));
    const float sin2_t = eta * eta * std::max(0.0f, 1 - cos_i * cos_i);
    if (sin2_t >= 1) {
        r.total_internal = true;
        return r;
    }
    const float cos_t = std::sqrt(1 - sin2_t);
    r.dir = normalize(d * eta + n * (eta * cos_i - cos_t));
    r.fresnel = fresnel_dielectric(cos_i, cos_t, eta);
    return r;
}

/// `p` moved by `eps` along the unit vector `side`.
inline Vec3f offset_point(const Vec3f& p, const Vec3f& side, float eps) noexcept { return p + side * eps; }

/// The offset scale of a triangle: its largest |coordinate| (see the file comment).
inline float offset_scale(const Trianglef& t) noexcept {
    float s = 0;
    for (const Vec3f* v : {&t.p0, &t.p1, &t.p2})
        s = std::max({s, std::abs(v->x), std::abs(v->y), std::abs(v->z)});
    return s;
}

namespace detail {

inline float max_channel(const Vec3f& c) noexcept { return std::max({c.x, c.y, c.z}); }

struct PathRay {
    Rayf ray;
    Vec3f weight;
    std::uint32_t pixel;
    std::uint32_t depth;
};

struct ShadowRay {
    Rayf ray;
    Vec3f radiance;   ///< added to the pixel when nothing blocks the ray
    std::uint32_t pixel;
};

struct Emit {
    std::uint32_t pixel;
    Vec3f radiance;
};

struct ChunkOut {
    std::vector<ShadowRay> shadow;
    std::vector<PathRay> reflection, refraction;
    std::vector<Emit> emit;
    void clear() {
        shadow.clear();
        reflection.clear();
        refraction.clear();
        emit.clear();
    }
};

/// Shades one traced path ray: what it sees locally (emit), its shadow rays and its children.
inline void shade(const SceneView& scene, const Config& cfg, const PathRay& pr, const Hitf& h, ChunkOut& out) {
    if (!h || h.prim >= scene.triangles.size()) {
        out.emit.push_back({pr.pixel, pr.weight * (scene.background ? *scene.background : cfg.background)});
        return;
    }
    static const io::Material default_material{};
    const Trianglef& tri = scene.triangles[h.prim];
    const std::uint32_t mid = h.prim < scene.material.size() ? scene.material[h.prim] : 0;
    const io::Material& m = mid < scene.materials.size() ? scene.materials[mid] : default_material;

    const Vec3f d = normalize(pr.ray.dir);
    const Vec3f e1 = tri.p1 - tri.p0, e2 = tri.p2 - tri.p0;
    Vec3f ng = cross(e1, e2);
    const float len = length(ng);
    ng = len > 0 ? ng * (1 / len) : -d;   // a degenerate triangle faces the ray
    const bool front = dot(d, ng) < 0;
    const Vec3f n = front ? ng : -ng;     // faces the side the ray came from
    const Vec3f p = tri.p0 + e1 * h.u + e2 * h.v;
    const float eps = cfg.offset * offset_scale(tri);

    Vec3f local = cfg.ambient * m.diffuse;
    if (scene.lights.empty()) local += m.diffuse * (cfg.headlight * std::abs(dot(d, n)));
    local = pr.weight * local;
    if (max_channel(local) > 0) out.emit.push_back({pr.pixel, local});

    if (cfg.shadows) {
        const bool phong = m.shininess > 0 && reflects(m);
        for (const io::Light& light : scene.lights) {
            const Vec3f to_light = light.position - p;
            const float dist = length(to_light);
            if (!(dist > 0)) continue;
            const Vec3f l = to_light * (1 / dist);
            const float ndl = dot(n, l);
            if (!(ndl > 0)) continue;   // the light is behind the surface (seen from the ray's side)
            Vec3f c = m.diffuse * ndl;
            if (phong) {
                const float s = dot(reflect(-l, n), -d);
                if (s > 0) c += m.specular * std::pow(s, m.shininess);
            }
            c = pr.weight * c * light.color;
            if (!(max_channel(c) > 0) || max_channel(c) < cfg.min_weight) continue;
            ShadowRay sr;
            sr.ray.org = offset_point(p, n, eps);
            sr.ray.dir = light.position - sr.ray.org;
            sr.ray.tmin = 0;
            sr.ray.tmax = 1 - 1.0f / 4096;   // stop just short of the light
            sr.radiance = c;
            sr.pixel = pr.pixel;
            out.shadow.push_back(sr);
        }
    }

    if (int(pr.depth) >= cfg.max_depth) return;
    Vec3f kr = cfg.reflections ? m.specular : Vec3f{0, 0, 0};
    Vec3f kt{0, 0, 0};
    Refraction rf;
    rf.total_internal = true;
    if (cfg.refractions && refracts(m)) {
        const float eta = front ? 1 / m.ior : m.ior;   // entering: 1 -> ior; leaving: ior -> 1
        rf = refract(d, n, eta);
        const float f = rf.total_internal ? 1.0f : rf.fresnel;
        if (cfg.reflections) kr += Vec3f{1, 1, 1} * (m.transmission * f);
        if (!rf.total_internal) kt = Vec3f{1, 1, 1} * (m.transmission * (1 - f));
    }
    const Vec3f wr = pr.weight * kr, wt = pr.weight * kt;
    if (max_channel(wr) > 0 && max_channel(wr) >= cfg.min_weight) {
        PathRay c;
        c.ray.org = offset_point(p, n, eps);
        c.ray.dir = reflect(d, n);
        c.weight = wr;
        c.pixel = pr.pixel;
        c.depth = pr.depth + 1;
        out.reflection.push_back(c);
    }
    if (!rf.total_internal && max_channel(wt) > 0 && max_channel(wt) >= cfg.min_weight) {
        PathRay c;
        c.ray.org = offset_point(p, -n, eps);
        c.ray.dir = rf.dir;
        c.weight = wt;
        c.pixel = pr.pixel;
        c.depth = pr.depth + 1;
        out.refraction.push_back(c);
    }
}

using clock = std::chrono::steady_clock;
inline double ms_since(clock::time_point t0) { return std::chrono::duration<double, std::milli>(clock::now() - t0).count(); }

/// Rays [i, e) of queue q (its entries' .ray) in packets of up to 16: trace(rays, first).
template <class Q, class F>
void for_each_packet(std::span<const Q> q, std::size_t i, std::size_t e, const F& trace) {
    Rayf rays[16];
    for (; i < e; i += 16) {
        const std::size_t n = std::min<std::size_t>(16, e - i);
        for (std::size_t k = 0; k < n; ++k) rays[k] = q[i + k].ray;
        trace(std::span<const Rayf>(rays, n), i);
    }
}

/// Closest hits of queue q; `coherent` (primary rays) goes in packets through a PacketTracer.
template <class T, class Exec>
void trace_closest(const T& tracer, std::span<const PathRay> q, std::vector<Hitf>& hits, bool coherent, const Config& cfg, const Exec& ex) {
    hits.resize(q.size());
    const std::size_t chunk = std::max<std::size_t>(1, cfg.chunk_rays);
    ex.for_tasks((q.size() + chunk - 1) / chunk, [&](std::size_t k) {
        const std::size_t e = std::min(q.size(), (k + 1) * chunk);
        if constexpr (PacketTracer<T>) {
            if (coherent && cfg.packets) {
                for_each_packet(q, k * chunk, e, [&](std::span<const Rayf> rays, std::size_t first) {
                    tracer.intersect_packet(rays, std::span<Hitf>(hits.data() + first, rays.size()));
                });
                return;
            }
        }
        for (std::size_t i = k * chunk; i < e; ++i) hits[i] = tracer.intersect(q[i].ray);
    });
}

/// Shadow rays of queue q (in packets through a PacketTracer with cfg.shadow_packets).
template <class T, class Exec>
void trace_any(const T& tracer, std::span<const ShadowRay> q, std::vector<std::uint8_t>& blocked, const Config& cfg, const Exec& ex) {
    blocked.resize(q.size());
    const std::size_t chunk = std::max<std::size_t>(1, cfg.chunk_rays);
    ex.for_tasks((q.size() + chunk - 1) / chunk, [&](std::size_t k) {
        const std::size_t e = std::min(q.size(), (k + 1) * chunk);
        if constexpr (PacketTracer<T>) {
            if (cfg.shadow_packets) {
                for_each_packet(q, k * chunk, e, [&](std::span<const Rayf> rays, std::size_t first) {
                    tracer.occluded_packet(rays, std::span<std::uint8_t>(blocked.data() + first, rays.size()));
                });
                return;
            }
        }
        for (std::size_t i = k * chunk; i < e; ++i) blocked[i] = tracer.occluded(q[i].ray) ? 1 : 0;
    });
}

/// Reusable queues of one render.
struct Work {
    std::vector<PathRay> queue[3];   // primary, reflection, refraction of the current depth
    std::vector<PathRay> next[3];
    std::vector<Hitf> hits;
    std::vector<ShadowRay> shadow;
    std::vector<std::uint8_t> blocked;
    std::vector<ChunkOut> chunks;
};

/// Traces `primary` (one path per entry, pixel = index into `pixels`) through every depth,
/// adding what each path sees into `pixels`.
template <class T, class Exec>
void run_paths(const T& tracer, const SceneView& scene, const Config& cfg, const Exec& ex, Work& w, std::span<Vec3f> pixels,
               Stats& st) {
    const std::size_t chunk = std::max<std::size_t>(1, cfg.chunk_rays);
    for (int depth = 0; depth <= cfg.max_depth; ++depth) {
        bool any = false;
        for (auto& q : w.queue) any = any || !q.empty();
        if (!any) break;
        if (depth > 0) st.depth_reached = std::max(st.depth_reached, depth);
        w.shadow.clear();
        for (auto& q : w.next) q.clear();
        for (int qi = 0; qi < 3; ++qi) {
            const std::vector<PathRay>& q = w.queue[qi];
            if (q.empty()) continue;
            const RayKind kind = qi == 0 ? RayKind::primary : qi == 1 ? RayKind::reflection : RayKind::refraction;
            auto t0 = clock::now();
            trace_closest(tracer, std::span<const PathRay>(q), w.hits, kind == RayKind::primary, cfg, ex);
            st.trace_ms[std::size_t(kind)] += ms_since(t0);
            st.rays[std::size_t(kind)] += q.size();

            t0 = clock::now();
            const std::size_t nchunks = (q.size() + chunk - 1) / chunk;
            if (w.chunks.size() < nchunks) w.chunks.resize(nchunks);
            ex.for_tasks(nchunks, [&](std::size_t k) {
                ChunkOut& o = w.chunks[k];
                o.clear();
                const std::size_t e = std::min(q.size(), (k + 1) * chunk);
                for (std::size_t i = k * chunk; i < e; ++i) shade(scene, cfg, q[i], w.hits[i], o);
            });
            // Merge in chunk order: the same queues and sums whatever the executor.
            for (std::size_t k = 0; k < nchunks; ++k) {
                const ChunkOut& o = w.chunks[k];
                for (const Emit& em : o.emit) pixels[em.pixel] += em.radiance;
                w.shadow.insert(w.shadow.end(), o.shadow.begin(), o.shadow.end());
                w.next[1].insert(w.next[1].end(), o.reflection.begin(), o.reflection.end());
                w.next[2].insert(w.next[2].end(), o.refraction.begin(), o.refraction.end());
            }
            st.shade_ms += ms_since(t0);
        }
        if (!w.shadow.empty()) {
            auto t0 = clock::now();
            trace_any(tracer, std::span<const ShadowRay>(w.shadow), w.blocked, cfg, ex);
            st.trace_ms[std::size_t(RayKind::shadow)] += ms_since(t0);
            st.rays[std::size_t(RayKind::shadow)] += w.shadow.size();
            t0 = clock::now();
            for (std::size_t i = 0; i < w.shadow.size(); ++i)
                if (!w.blocked[i]) pixels[w.shadow[i].pixel] += w.shadow[i].radiance;
            st.shade_ms += ms_since(t0);
        }
        for (int qi = 0; qi < 3; ++qi) std::swap(w.queue[qi], w.next[qi]);
    }
    for (auto& q : w.queue) q.clear();
}

} // namespace detail

/// Traces one path per entry of `rays` (as primary rays) and writes what each sees into
/// `out[i]` (overwritten; `out.size()` must be `rays.size()`). For tests and custom cameras.
template <Tracer T, TaskExecutor Exec>
Stats render_rays(const T& tracer, const SceneView& scene, std::span<const Rayf> rays, std::span<Vec3f> out, const Config& cfg,
                  const Exec& ex) {
    Stats st;
    detail::Work w;
    std::fill(out.begin(), out.end(), Vec3f{0, 0, 0});
    const std::size_t n = std::min(rays.size(), out.size());
    const std::size_t batch = std::max<std::size_t>(1, cfg.batch_rays);
    for (std::size_t b = 0; b < n; b += batch) {
        const auto t0 = detail::clock::now();
        w.queue[0].clear();
        for (std::size_t i = b; i < std::min(n, b + batch); ++i)
            w.queue[0].push_back({rays[i], Vec3f{1, 1, 1}, std::uint32_t(i), 0});
        st.shade_ms += detail::ms_since(t0);
        detail::run_paths(tracer, scene, cfg, ex, w, out, st);
    }
    return st;
}

/// Renders `cam`'s image into `img` (resized; linear RGB). Pixels are traced in 16x16 tiles,
/// `cfg.batch_rays` primary rays per wavefront batch. Returns the rays traced and times per kind.
template <Tracer T, Camera C, TaskExecutor Exec>
Stats render(const T& tracer, const SceneView& scene, const C& cam, Image& img, const Config& cfg, const Exec& ex) {
    constexpr int tile = 16;
    const int w = std::max(0, int(cam.width())), h = std::max(0, int(cam.height()));
    img.width = w;
    img.height = h;
    img.pixels.assign(std::size_t(w) * std::size_t(h), Vec3f{0, 0, 0});
    Stats st;
    detail::Work work;
    const int tiles_x = (w + tile - 1) / tile, tiles_y = (h + tile - 1) / tile;
    const std::size_t tiles = std::size_t(tiles_x) * std::size_t(tiles_y);
    const std::size_t batch = std::max<std::size_t>(1, cfg.batch_rays);
    std::size_t k = 0;
    while (k < tiles) {
        const auto t0 = detail::clock::now();
        work.queue[0].clear();
        for (; k < tiles && work.queue[0].size() < batch; ++k) {
            const int x0 = int(k % std::size_t(tiles_x)) * tile, y0 = int(k / std::size_t(tiles_x)) * tile;
            for (int y = y0; y < std::min(h, y0 + tile); ++y)
                for (int x = x0; x < std::min(w, x0 + tile); ++x)
                    work.queue[0].push_back({cam.ray(x, y), Vec3f{1, 1, 1}, std::uint32_t(std::size_t(y) * std::size_t(w) + std::size_t(x)), 0});
        }
        st.shade_ms += detail::ms_since(t0);
        detail::run_paths(tracer, scene, cfg, ex, work, std::span<Vec3f>(img.pixels), st);
    }
    return st;
}

} // namespace dynbvh::render
