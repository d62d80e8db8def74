// The Whitted renderer (bench/render/whitted.hpp): a mirror sphere over a checkered plane gives exactly
// the pixel classes an independent double-precision computation predicts; a ray through a glass slab
// comes out parallel, displaced by the analytic amount, dimmed by the exact Fresnel factor; total
// internal reflection starts at the critical angle; ray counts match a hand count on a tiny scene and
// are zero where no material or light calls for them; results do not depend on the executor or tracer;
// and dynbvh-study --effects auto reports the counts per kind.
#include <doctest/doctest.h>

#include <render/whitted.hpp>

#include <cmath>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <mutex>
#include <numbers>
#include <sstream>
#include <string>
#include <type_traits>
#include <vector>

#include <dynbvh/executor.hpp>
#include <dynbvh/lbvh.hpp>
#include <dynbvh/ploc.hpp>
#include <dynbvh/wide_blocks.hpp>
#include <scenes/builtin.hpp>

using namespace dynbvh;
using render::RayKind;

namespace {

/// A pinhole camera for the tests (row 0 at the top), independent of the study's RayGen.
struct Pinhole {
    int w = 1, h = 1;
    Vec3f eye, corner, du, dv;
    Pinhole(Vec3f from, Vec3f at, float fov_y_deg, int width, int height) : w(width), h(height), eye(from) {
        const Vec3f fwd = normalize(at - from);
        const Vec3f right = normalize(cross(fwd, Vec3f{0, 1, 0}));
        const Vec3f up = cross(right, fwd);
        const float hh = std::tan(0.5f * fov_y_deg * std::numbers::pi_v<float> / 180), hw = hh * float(w) / float(h);
        du = right * (2 * hw / float(w));
        dv = up * (-2 * hh / float(h));
        corner = fwd - right * hw + up * hh;
    }
    int width() const { return w; }
    int height() const { return h; }
    Rayf ray(int x, int y) const {
        Rayf r;
        r.org = eye;
        r.dir = corner + du * (float(x) + 0.5f) + dv * (float(y) + 0.5f);
        return r;
    }
};

/// Explicit rays as a camera: pixel (x, y) = rays[y * w + x].
struct RayList {
    int w, h;
    std::vector<Rayf> rays;
    int width() const { return w; }
    int height() const { return h; }
    Rayf ray(int x, int y) const { return rays[std::size_t(y * w + x)]; }
};

struct TestScene {
    std::vector<Trianglef> tris;
    std::vector<std::uint32_t> mat;
    std::vector<io::Material> materials;
    std::vector<io::Light> lights;
    /// Quad a b c d (counter-clockwise seen from the side its normal points to) as two triangles.
    void quad(Vec3f a, Vec3f b, Vec3f c, Vec3f d, std::uint32_t m) {
        tris.push_back({a, b, c});
        tris.push_back({a, c, d});
        mat.insert(mat.end(), 2, m);
    }
    render::SceneView view() const { return {tris, mat, materials, lights, std::nullopt}; }
};

/// Renders `cam` over an LBVH of the scene with the serial executor.
template <class Cam>
render::Stats render_scene(const TestScene& s, const Cam& cam, render::Image& img, const render::Config& cfg) {
    const auto bvh = lbvh::build(std::span<const Trianglef>(s.tris));
    return render::render(render::bvh_tracer(bvh, s.tris), s.view(), cam, img, cfg, exec::serial{});
}

// ---------------------------------------------------------------------------------------------
// Mirror sphere over a checkered plane.

constexpr int plane_half = 4;   // the plane covers [-4, 4]^2 at y = 0 in unit cells
const Vec3f sphere_centre{0, 1, 0};
constexpr float sphere_radius = 0.9f;

TestScene mirror_scene() {
    TestScene s;
    s.materials = {io::Material{.name = "red", .diffuse = {1, 0, 0}}, io::Material{.name = "green", .diffuse = {0, 1, 0}},
                   io::Material{.name = "mirror", .diffuse = {0, 0, 0}, .specular = {0.5f, 0.5f, 0.5f}}};
    for (int i = -plane_half; i < plane_half; ++i)
        for (int j = -plane_half; j < plane_half; ++j) {
            const float x = float(i), z = float(j);
            s.quad({x, 0, z}, {x, 0, z + 1}, {x + 1, 0, z + 1}, {x + 1, 0, z}, std::uint32_t(((i + j) % 2 + 2) % 2));
        }
    const int slices = 24, stacks = 12;
    auto vtx = [&](int k, int sl) {
        const float th = std::numbers::pi_v<float> * float(k) / float(stacks), ph = 2 * std::numbers::pi_v<float> * float(sl) / float(slices);
        return sphere_centre + Vec3f{std::sin(th) * std::cos(ph), std::cos(th), std::sin(th) * std::sin(ph)} * sphere_radius;
    };
    for (int k = 0; k < stacks; ++k)
        for (int sl = 0; sl < slices; ++sl) {
            const Vec3f a = vtx(k, sl), b = vtx(k + 1, sl), c = vtx(k + 1, sl + 1), d = vtx(k, sl + 1);
            if (k > 0) {
                s.tris.push_back({a, c, d});
                s.mat.push_back(2);
            }
            if (k + 1 < stacks) {
                s.tris.push_back({a, b, c});
                s.mat.push_back(2);
            }
        }
    return s;
}

enum Cls { sky, red, green, mirror_sky, mirror_red, mirror_green, other };
const char* cls_name(int c) {
    static const char* n[] = {"sky", "red", "green", "mirror->sky", "mirror->red", "mirror->green", "other"};
    return n[c];
}

/// The renderer's class of a pixel, from its exact colour (ambient 1, no lights, background blue,
/// mirror weight 1/2: every class has its own colour, all exactly representable).
int class_of_colour(const Vec3f& c) {
    const Vec3f table[6] = {{0, 0, 1}, {1, 0, 0}, {0, 1, 0}, {0, 0, 0.5f}, {0.5f, 0, 0}, {0, 0.5f, 0}};
    for (int k = 0; k < 6; ++k)
        if (c == table[k]) return k;
    return other;
}

using V3 = Vec3<double>;
V3 to_d(const Vec3f& v) { return {double(v.x), double(v.y), double(v.z)}; }

/// Independent reference (double precision, no BVH, no renderer code): the class of the ray
/// (o, d) by brute-force ray-facet intersection with the sphere's triangles, mirror reflection about
/// the hit facet's normal, and the analytic plane y = 0. `near` is set when the ray passes within a
/// tiny band of a class boundary (see the test's rule).
struct Reference {
    std::vector<std::array<V3, 3>> facets;
    static constexpr double bary_band = 1e-3;    // barycentric margin to a facet edge
    static constexpr double plane_band = 1e-3;   // distance to a cell line or the plane's border (cells are 1 wide)

    explicit Reference(const TestScene& s) {
        for (std::size_t i = 0; i < s.tris.size(); ++i)
            if (s.mat[i] == 2) facets.push_back({to_d(s.tris[i].p0), to_d(s.tris[i].p1), to_d(s.tris[i].p2)});
    }
    /// The plane: red/green/sky; `near` when the hit is within plane_band of a cell line or the border.
    static int plane(const V3& o, const V3& d, bool& near) {
        if (!(d.y < 0)) return sky;
        const double t = -o.y / d.y;
        const double x = o.x + t * d.x, z = o.z + t * d.z;
        if (std::abs(x - std::round(x)) < plane_band || std::abs(z - std::round(z)) < plane_band) near = true;
        if (std::abs(x) >= plane_half || std::abs(z) >= plane_half) return sky;
        const long parity = ((long(std::floor(x)) + long(std::floor(z))) % 2 + 2) % 2;
        return parity == 0 ? red : green;
    }
    int classify(const V3& o, const V3& d, bool& near) const {
        double best = std::numeric_limits<double>::infinity(), best_margin = 0;
        const std::array<V3, 3>* hit = nullptr;
        double closest_miss = -std::numeric_limits<double>::infinity();   // largest negative margin of a facet plane crossed at t > 0
        for (const auto& f : facets) {
            const V3 e1 = f[1] - f[0], e2 = f[2] - f[0];
            const V3 pv = cross(d, e2);
            const double det = dot(e1, pv);
            if (std::abs(det) < 1e-300) continue;
            const V3 tv = o - f[0];
            const double u = dot(tv, pv) / det;
            const V3 qv = cross(tv, e1);
            const double v = dot(d, qv) / det, t = dot(e2, qv) / det;
            if (!(t > 0)) continue;
            const double margin = std::min({u, v, 1 - u - v});
            if (margin >= 0) {
                if (t < best) {
                    best = t;
                    hit = &f;
                    best_margin = margin;
                }
            } else {
                closest_miss = std::max(closest_miss, margin);
            }
        }
        if (!hit) {
            if (closest_miss > -bary_band) near = true;   // grazes the silhouette
            return plane(o, d, near);                     // the sphere is above the plane: no occlusion below it
        }
        if (best_margin < bary_band) near = true;         // next to a facet edge: the mirror normal jumps there
        const auto& f = *hit;
        const V3 n = normalize(cross(f[1] - f[0], f[2] - f[0]));
        const V3 p = o + d * best;
        const V3 r = d - n * (2 * dot(d, n));
        // A convex mirror does not see itself: the reflected ray meets only the plane or the sky.
        return plane(p, r, near) + 3;
    }
};

// ---------------------------------------------------------------------------------------------

/// A Tracer that records every closest-hit ray (single-threaded use).
template <class Inner>
struct Recorder {
    Inner inner;
    mutable std::vector<Rayf> rays;
    Hitf intersect(const Rayf& r) const {
        rays.push_back(r);
        return inner.intersect(r);
    }
    bool occluded(const Rayf& r) const { return inner.occluded(r); }
};

/// Brute force as a Tracer (every triangle per ray).
struct BruteTracer {
    std::span<const Trianglef> tris;
    Hitf intersect(const Rayf& r) const { return brute_force_intersect<trace::robust, float>(tris, r); }
    bool occluded(const Rayf& r) const { return brute_force_occluded<trace::robust, float>(tris, r); }
};

/// A glass slab between z = 0 (normal +z) and z = -thickness (normal -z), 4 x 4 wide.
TestScene slab_scene(float thickness, float specular = 0) {
    TestScene s;
    s.materials = {io::Material{.name = "glass", .diffuse = {0, 0, 0}, .specular = {specular, specular, specular}, .transmission = 1, .ior = 1.5f}};
    const float h = 2, t = -thickness;
    s.quad({-h, -h, 0}, {h, -h, 0}, {h, h, 0}, {-h, h, 0}, 0);
    s.quad({-h, -h, t}, {-h, h, t}, {h, h, t}, {h, -h, t}, 0);
    return s;
}

} // namespace

static_assert(render::Tracer<render::BvhTracer<trace::robust, Bvh<>>>);
static_assert(render::Tracer<BruteTracer>);
static_assert(render::Camera<Pinhole>);

TEST_CASE("effects: a mirror sphere over a checkered plane gives exactly the expected pixel classes") {
    const TestScene s = mirror_scene();
    const Pinhole cam({0, 2.2f, 4.5f}, {0, 0.7f, 0}, 50, 96, 72);
    render::Config cfg{.ambient = {1, 1, 1}, .headlight = 0, .background = {0, 0, 1}};
    render::Image img;
    const render::Stats st = render_scene(s, cam, img, cfg);
    REQUIRE(img.pixels.size() == std::size_t(96 * 72));

    // Rule: every pixel's class (from its exact colour) must equal the reference class, except pixels
    // whose primary or reflected ray passes within the reference's band of a class boundary: within
    // 1e-3 (barycentric) of a sphere facet's edge or of missing the sphere, or hitting the plane
    // within 1e-3 of a cell line or of the plane's border. Such pixels may go either way (float
    // rounding, origin offset); they must be rare, and every class must be well represented.
    const Reference ref(s);
    int mismatches = 0, excused = 0, mirror_pixels = 0, mirror_excused = 0;
    int count[7] = {};
    for (int y = 0; y < cam.height(); ++y)
        for (int x = 0; x < cam.width(); ++x) {
            const Rayf r = cam.ray(x, y);
            bool near = false;
            const int want = ref.classify(to_d(r.org), to_d(r.dir), near);
            const int got = class_of_colour(img.pixels[std::size_t(y * cam.width() + x)]);
            ++count[got];
            if (want >= mirror_sky) {
                ++mirror_pixels;
                mirror_excused += near;
            }
            excused += near;
            if (got != want && !near) {
                ++mismatches;
                if (mismatches <= 5) MESSAGE("pixel (" << x << ", " << y << "): rendered " << cls_name(got) << ", expected " << cls_name(want));
            }
        }
    CHECK(mismatches == 0);
    CHECK(count[other] == 0);
    CHECK(excused < 96 * 72 / 100);
    for (int c = sky; c <= mirror_green; ++c) CHECK_MESSAGE(count[c] >= 20, cls_name(c) << ": " << count[c] << " pixels");
    // One reflection ray per pixel that sees the mirror, nothing else.
    CHECK(st.count(RayKind::primary) == 96u * 72u);
    CHECK(st.count(RayKind::shadow) == 0);
    CHECK(st.count(RayKind::refraction) == 0);
    CHECK(std::abs(double(st.count(RayKind::reflection)) - mirror_pixels) <= mirror_excused);
    CHECK(st.depth_reached == 1);
}

TEST_CASE("effects: Snell, exact Fresnel and the lateral displacement through a glass slab") {
    const float thickness = 1, n = 1.5f;
    const TestScene s = slab_scene(thickness);
    const auto bvh = lbvh::build(std::span<const Trianglef>(s.tris));
    for (double deg : {0.0, 20.0, 45.0, 70.0}) {
        CAPTURE(deg);
        const double th = deg * std::numbers::pi / 180, tp = std::asin(std::sin(th) / n);
        const Vec3f d{float(std::sin(th)), 0, float(-std::cos(th))};
        Rayf ray;
        ray.org = -d * 5;   // through (0, 0, 0)
        ray.dir = d;
        Recorder<render::BvhTracer<trace::robust, Bvh<>>> rec{render::bvh_tracer(bvh, s.tris), {}};
        std::vector<Vec3f> out(1);
        const render::Config cfg{.ambient = {0, 0, 0}, .background = {0, 0, 1}, .reflections = false};
        const render::Stats st = render::render_rays(rec, s.view(), std::span<const Rayf>(&ray, 1), out, cfg, exec::serial{});
        CHECK(st.count(RayKind::primary) == 1);
        CHECK(st.count(RayKind::refraction) == 2);   // into the slab, out of it
        CHECK(st.count(RayKind::reflection) == 0);
        REQUIRE(rec.rays.size() == 3);
        // Inside: Snell's law.
        const Vec3f in = normalize(rec.rays[1].dir);
        CHECK(double(in.x) == doctest::Approx(std::sin(tp)).epsilon(1e-5));
        CHECK(in.z < 0);
        // Out: parallel to the incident ray, displaced sideways by t sin(theta - theta') / cos(theta').
        const Rayf& exit = rec.rays[2];
        CHECK(std::abs(double(exit.org.z) + thickness) < 1e-4);
        const Vec3f dout = normalize(exit.dir);
        CHECK(length(dout - d) < 1e-5f);
        const double displaced = double(length(cross(exit.org, d)));   // distance of the exit line from the incident line through 0
        const double expected = thickness * std::sin(th - tp) / std::cos(tp);
        CHECK(std::abs(displaced - expected) < 1e-4);
        // Colour: the background through two interfaces, each transmitting 1 - F (reflections off);
        // F from Fresnel's equations in their sine/tangent form.
        double f = std::pow((n - 1) / (n + 1), 2);
        if (th > 0) {
            const double rs = std::sin(th - tp) / std::sin(th + tp), rp = std::tan(th - tp) / std::tan(th + tp);
            f = 0.5 * (rs * rs + rp * rp);
        }
        CHECK(double(out[0].z) == doctest::Approx((1 - f) * (1 - f)).epsilon(1e-5));
        CHECK(out[0].x == 0);
    }
}

TEST_CASE("effects: total internal reflection starts at the critical angle") {
    const TestScene s = slab_scene(1);
    const auto bvh = lbvh::build(std::span<const Trianglef>(s.tris));
    const double critical = std::asin(1 / 1.5) * 180 / std::numbers::pi;   // 41.81 degrees
    for (double deg : {0.0, 30.0, critical - 0.5, critical + 0.5, 60.0, 70.0}) {
        CAPTURE(deg);
        const double th = deg * std::numbers::pi / 180;
        Rayf ray;
        ray.org = {0, 0, -0.5f};   // inside the glass, towards the top face
        ray.dir = {float(std::sin(th)), 0, float(std::cos(th))};
        std::vector<Vec3f> out(1);
        const render::Config cfg{.max_depth = 1, .min_weight = 0};
        const render::Stats st = render::render_rays(render::bvh_tracer(bvh, s.tris), s.view(), std::span<const Rayf>(&ray, 1), out, cfg,
                                                     exec::serial{});
        CHECK(st.count(RayKind::primary) == 1);
        CHECK(st.count(RayKind::reflection) == 1);   // Fresnel share; all of it beyond the critical angle
        CHECK(st.count(RayKind::refraction) == (deg < critical ? 1u : 0u));
    }
    // The optics helper itself: TIR flag and F = 1 beyond the critical angle, F < 1 below.
    const Vec3f n{0, 0, -1};
    const float below = float((critical - 0.01) * std::numbers::pi / 180), above = float((critical + 0.01) * std::numbers::pi / 180);
    const auto r1 = render::refract({std::sin(below), 0, std::cos(below)}, n, 1.5f);
    const auto r2 = render::refract({std::sin(above), 0, std::cos(above)}, n, 1.5f);
    CHECK(!r1.total_internal);
    CHECK(r1.fresnel < 1);
    CHECK(r2.total_internal);
    CHECK(r2.fresnel == 1);
}

TEST_CASE("effects: ray counts match a hand count on a 2x2 image with one mirror quad and one light") {
    TestScene s;
    s.materials = {io::Material{.name = "mirror", .diffuse = {0.5f, 0.5f, 0.5f}, .specular = {0.5f, 0.5f, 0.5f}},
                   io::Material{.name = "wall", .diffuse = {0.8f, 0.8f, 0.8f}}};
    s.quad({0, -1, 0}, {2, -1, 0}, {2, 1, 0}, {0, 1, 0}, 0);                  // mirror M, z = 0, facing +z
    s.quad({0.25f, -0.25f, 2}, {0.25f, 0.25f, 2}, {0.75f, 0.25f, 2}, {0.75f, -0.25f, 2}, 1);   // wall W above it, z = 2
    s.lights = {io::Light{.position = {1.5f, 0, 1}}};
    auto down = [](Vec3f o) { return Rayf{o, {0, 0, -1}}; };
    // (0,0): M at (0.5, 0, 0): shadow ray, reflection up onto W, whose shading sends one more shadow ray.
    // (1,0): M at (1.5, 0.5, 0): shadow ray, reflection up past W (sky).
    // (0,1), (1,1): miss everything.
    const RayList cam{2, 2, {down({0.5f, 0, 1}), down({1.5f, 0.5f, 1}), down({3, 0, 1}), Rayf{{-1, 0, 1}, {0, 0, 1}}}};
    const render::Config base{};
    const Vec3f a = base.ambient, bg = base.background;
    const float r2 = std::sqrt(0.5f);
    render::Image img;
    {
        const render::Stats st = render_scene(s, cam, img, base);
        CHECK(st.count(RayKind::primary) == 4);
        CHECK(st.count(RayKind::shadow) == 3);
        CHECK(st.count(RayKind::reflection) == 2);
        CHECK(st.count(RayKind::refraction) == 0);
        CHECK(st.depth_reached == 1);
        // (0,0): ambient + direct at M, plus half of W's ambient + direct (light at 45 degrees both times).
        const Vec3f p0 = a * 0.5f + Vec3f{1, 1, 1} * (0.5f * r2) + (a * 0.8f + Vec3f{1, 1, 1} * (0.8f * r2)) * 0.5f;
        CHECK(length(img.pixels[0] - p0) < 1e-6f);
        const Vec3f p1 = a * 0.5f + Vec3f{1, 1, 1} * (0.5f / std::sqrt(1.25f)) + bg * 0.5f;
        CHECK(length(img.pixels[1] - p1) < 1e-6f);
        CHECK(img.pixels[2] == bg);
        CHECK(img.pixels[3] == bg);
    }
    {   // Depth 0: no reflection rays, so W is never shaded: 2 shadow rays.
        render::Config c = base;
        c.max_depth = 0;
        const render::Stats st = render_scene(s, cam, img, c);
        CHECK(st.count(RayKind::primary) == 4);
        CHECK(st.count(RayKind::shadow) == 2);
        CHECK(st.count(RayKind::reflection) == 0);
    }
    {   // Light behind M: M's hits send no shadow ray; W's does, and M blocks it (no direct light on W).
        TestScene t = s;
        t.lights = {io::Light{.position = {1.5f, 0, -1}}};
        const render::Stats st = render_scene(t, cam, img, base);
        CHECK(st.count(RayKind::shadow) == 1);
        CHECK(st.count(RayKind::reflection) == 2);
        const Vec3f p0 = a * 0.5f + a * 0.8f * 0.5f;
        CHECK(length(img.pixels[0] - p0) < 1e-6f);
    }
}

TEST_CASE("effects: no secondary rays where no material or light calls for them") {
    TestScene s = mirror_scene();
    const Pinhole cam({0, 2.2f, 4.5f}, {0, 0.7f, 0}, 50, 32, 24);
    render::Image img;
    {   // Matte materials, no lights: primary rays only.
        TestScene t = s;
        t.materials[2] = io::Material{.name = "matte", .diffuse = {0.5f, 0.5f, 0.5f}};
        const render::Stats st = render_scene(t, cam, img, {});
        CHECK(st.count(RayKind::primary) == 32u * 24u);
        CHECK(st.count(RayKind::shadow) == 0);
        CHECK(st.count(RayKind::reflection) == 0);
        CHECK(st.count(RayKind::refraction) == 0);
        CHECK(st.depth_reached == 0);
        CHECK(!render::scene_needs(t.materials, t.lights).reflections);
        // A light: shadow rays only.
        t.lights = {io::Light{.position = {2, 5, 3}}};
        const render::Stats st2 = render_scene(t, cam, img, {});
        CHECK(st2.count(RayKind::shadow) > 0);
        CHECK(st2.count(RayKind::shadow) <= st2.count(RayKind::primary));
        CHECK(st2.count(RayKind::reflection) == 0);
        CHECK(st2.count(RayKind::refraction) == 0);
    }
    {   // The mirror with reflections switched off (--effects primary), and a mirror scene with no light.
        render::Config c;
        c.reflections = false;
        const render::Stats st = render_scene(s, cam, img, c);
        CHECK(st.count(RayKind::reflection) == 0);
        const render::Stats st2 = render_scene(s, cam, img, {});
        CHECK(st2.count(RayKind::reflection) > 0);
        CHECK(st2.count(RayKind::shadow) == 0);
        CHECK(st2.count(RayKind::refraction) == 0);
    }
    {   // Built-in scenes: cloth-ball is matte (shadows only); funnel's glass asks for both.
        for (const char* name : {"cloth-ball", "funnel"}) {
            CAPTURE(name);
            auto scene = scenes::make_builtin(name, {.scale = 0.02});
            io::Frame f;
            scene->frame(scene->frame_count() * 2 / 3, f);
            const auto bvh = ploc::build(std::span<const Trianglef>(f.triangles));
            const Pinhole c(f.camera.from, f.camera.at, f.camera.fov_y_deg, 48, 27);
            const render::Stats st = render::render(render::bvh_tracer(bvh, f.triangles), render::scene_view(f, scene->info()), c, img, {},
                                                    exec::serial{});
            const bool glass = std::string(name) == "funnel";
            CHECK(st.count(RayKind::primary) == 48u * 27u);
            CHECK(st.count(RayKind::shadow) > 0);
            CHECK((st.count(RayKind::reflection) > 0) == glass);
            CHECK((st.count(RayKind::refraction) > 0) == glass);
        }
    }
}

TEST_CASE("effects: the same image and counts whatever the executor or tracer") {
    auto scene = scenes::make_builtin("funnel", {.scale = 0.02});
    io::Frame f;
    scene->frame(100, f);
    const auto bvh = lbvh::build(std::span<const Trianglef>(f.triangles));
    const Pinhole cam(f.camera.from, f.camera.at, f.camera.fov_y_deg, 40, 24);
    const render::SceneView view = render::scene_view(f, scene->info());
    const render::Config cfg{.batch_rays = 200, .chunk_rays = 16};   // several batches and chunks
    render::Image a, b, c;
    const render::Stats sa = render::render(render::bvh_tracer(bvh, f.triangles), view, cam, a, cfg, exec::serial{});
    const render::Stats sb = render::render(render::bvh_tracer(bvh, f.triangles), view, cam, b, cfg, exec::default_executor{});
    const render::Stats sc = render::render(BruteTracer{f.triangles}, view, cam, c, cfg, exec::serial{});
    CHECK(sa.count(RayKind::refraction) > 0);
    CHECK(sa.rays == sb.rays);
    CHECK(sa.rays == sc.rays);
    CHECK(a.pixels == b.pixels);
    CHECK(a.pixels == c.pixels);
}

namespace {
/// A PacketTracer over a block tree that counts its packet calls.
template <class Tree>
struct CountingPacketTracer {
    render::BvhTracer<trace::robust, Tree> inner;
    std::size_t* closest_packets;
    std::size_t* any_packets;
    Hitf intersect(const Rayf& r) const { return inner.intersect(r); }
    bool occluded(const Rayf& r) const { return inner.occluded(r); }
    void intersect_packet(std::span<const Rayf> r, std::span<Hitf> out) const {
        ++*closest_packets;
        inner.intersect_packet(r, out);
    }
    void occluded_packet(std::span<const Rayf> r, std::span<std::uint8_t> out) const {
        ++*any_packets;
        inner.occluded_packet(r, out);
    }
};
} // namespace

TEST_CASE("effects: primary and shadow rays in packets give the single-ray image and counts") {
    std::size_t shadow_rays = 0;
    for (const char* name : {"funnel", "cloth-ball"}) {
        CAPTURE(name);
        auto scene = scenes::make_builtin(name, {.scale = 0.02});
        io::Frame f;
        scene->frame(10, f);
        const auto bvh = lbvh::build(std::span<const Trianglef>(f.triangles));
        const auto blocks = make_wide_blocks<8>(bvh, std::span<const Trianglef>(f.triangles));
        static_assert(render::PacketTracer<decltype(render::bvh_tracer(blocks, f.triangles))>);
        static_assert(!render::PacketTracer<decltype(render::bvh_tracer(bvh, f.triangles))>);   // binary: single rays
        const Pinhole cam(f.camera.from, f.camera.at, f.camera.fov_y_deg, 37, 23);   // partial packets at row ends
        const render::SceneView view = render::scene_view(f, scene->info());
        const render::Config cfg{.batch_rays = 300, .chunk_rays = 40, .shadow_packets = true};   // chunks not a multiple of 16
        render::Config single = cfg;
        single.packets = single.shadow_packets = false;
        std::size_t closest = 0, any = 0;
        const CountingPacketTracer<std::remove_cvref_t<decltype(blocks)>> counting{render::bvh_tracer(blocks, f.triangles), &closest, &any};
        render::Image ref, packed, unpacked;
        const render::Stats sr = render::render(render::bvh_tracer(bvh, f.triangles), view, cam, ref, cfg, exec::serial{});
        const render::Stats sp = render::render(counting, view, cam, packed, cfg, exec::default_executor{});
        const std::size_t packets_used = closest, shadow_packets_used = any;
        const render::Stats su = render::render(counting, view, cam, unpacked, single, exec::serial{});
        CHECK(sr.rays == sp.rays);
        CHECK(sr.rays == su.rays);
        CHECK(ref.pixels == packed.pixels);
        CHECK(ref.pixels == unpacked.pixels);
        // primaries went in packets of <= 16 (each chunk of 40 in 3), shadow rays too where there are any
        CHECK(packets_used >= sr.count(RayKind::primary) / 16);
        CHECK(closest == packets_used);   // packets = false: no packet call
        if (sr.count(RayKind::shadow) > 0) CHECK(shadow_packets_used > 0);
        CHECK(any == shadow_packets_used);
        shadow_rays += sr.count(RayKind::shadow);
    }
    CHECK(shadow_rays > 0);   // the shadow packets were exercised
}

#if defined(DYNBVH_STUDY_EXE)
namespace {

std::vector<std::vector<std::string>> read_csv(const std::filesystem::path& p) {
    std::ifstream in(p);
    std::vector<std::vector<std::string>> rows;
    std::string line;
    while (std::getline(in, line)) {
        std::vector<std::string> cells(1);
        for (char ch : line) {
            if (ch == ',') cells.emplace_back();
            else cells.back() += ch;
        }
        rows.push_back(cells);
    }
    return rows;
}

} // namespace

TEST_CASE("effects: dynbvh-study --effects auto reports rays per kind; primary (the default) reports none") {
    const std::filesystem::path out = std::filesystem::path(DYNBVH_STUDY_TMP) / "auto";
    std::filesystem::remove_all(out);
    std::filesystem::create_directories(out);
    for (const char* mode : {"auto", "primary"}) {
        CAPTURE(mode);
        const std::filesystem::path dir = out / mode;
        const std::string cmd = std::string("\"") + DYNBVH_STUDY_EXE +
                                "\" --scenes funnel,cloth-ball --scale 0.02 --frames 1 --builders lbvh,ploc --res 48x27 --images 1 "
                                "--threads 2 --no-warmup --effects " + mode + " --out \"" + dir.string() + "\" > \"" +
                                (out / (std::string(mode) + ".log")).string() + "\" 2>&1";
        REQUIRE(std::system(cmd.c_str()) == 0);
        const auto rows = read_csv(dir / "study.csv");
        REQUIRE(rows.size() == 5);   // header + 2 scenes x 2 builders x 1 frame
        REQUIRE(rows[0].size() == 30);
        CHECK(rows[0][14] == "rays_primary");
        CHECK(rows[0][17] == "rays_refraction");
        for (std::size_t i = 1; i < rows.size(); ++i) {
            const auto& r = rows[i];
            REQUIRE(r.size() == 30);
            if (std::string(mode) == "primary") {
                for (std::size_t k = 14; k < 23; ++k) CHECK(r[k].empty());
                continue;
            }
            const bool glass = r[1] == "funnel";
            CHECK(std::stoull(r[14]) == 48u * 27u);
            CHECK(std::stoull(r[15]) > 0);   // both scenes have a light
            CHECK((std::stoull(r[16]) > 0) == glass);
            CHECK((std::stoull(r[17]) > 0) == glass);
            CHECK(std::stod(r[18]) > 0);
        }
        std::ifstream md(dir / "report.md");
        std::stringstream ss;
        ss << md.rdbuf();
        CHECK((ss.str().find("## Effects") != std::string::npos) == (std::string(mode) == "auto"));
    }
}
#endif
