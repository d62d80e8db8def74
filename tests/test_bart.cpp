// Tests of the BART loader (io/bart.hpp) and its keyframe splines (io/bart_spline.hpp).
#include <doctest/doctest.h>

#include <dynbvh/io/bart.hpp>

#include <cmath>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <map>
#include <memory>
#include <random>
#include <string>

using namespace dynbvh;
using dynbvh::io::BartOptions;
using dynbvh::io::BartScene;
using dynbvh::io::Frame;
using dynbvh::io::LoadError;

namespace {

const char* const kKitchen = DYNBVH_DATA_DIR "/bart/kitchen/kitchen.aff";
const char* const kRobots = DYNBVH_DATA_DIR "/bart/robot/Robot.aff";
const char* const kMuseum = DYNBVH_DATA_DIR "/bart/museum/museum5.aff";

/// Real scenes are loaded once per process (each test file must stay fast, also under ASan).
const BartScene* real_scene(const char* path) {
    static std::map<std::string, std::unique_ptr<BartScene>> cache;
    auto it = cache.find(path);
    if (it == cache.end()) {
        std::error_code ec;
        if (!std::filesystem::exists(path, ec)) return nullptr;
        it = cache.emplace(path, io::load_bart(path)).first;
    }
    return it->second.get();
}

std::unique_ptr<BartScene> from_text(const std::string& text, const std::map<std::string, std::string>& includes = {},
                                     const BartOptions& opt = {}) {
    return io::load_bart_from_string(text, "main.aff", io::bart_file_map_resolver(includes), opt);
}

bool same_bits(const Trianglef& a, const Trianglef& b) { return std::memcmp(&a, &b, sizeof(Trianglef)) == 0; }

bool near(const Vec3f& a, const Vec3f& b, float eps = 1e-5f) {
    return std::abs(a.x - b.x) <= eps && std::abs(a.y - b.y) <= eps && std::abs(a.z - b.z) <= eps;
}

/// Loads `text` (with `includes`) and requires a LoadError naming `file` at `line` whose message contains `what`.
void require_error(const std::string& text, const std::map<std::string, std::string>& includes, const std::string& file,
                   std::size_t line, const std::string& what, const BartOptions& opt = {}) {
    CAPTURE(text);
    try {
        (void)from_text(text, includes, opt);
        FAIL("no LoadError for a malformed file (expected: " << what << ")");
    } catch (const LoadError& e) {
        CAPTURE(e.what());
        CHECK(e.file() == file);
        CHECK(e.where() == "line " + std::to_string(line));
        CHECK(std::string(e.what()).find(what) != std::string::npos);
    }
}

struct TempDir {
    std::filesystem::path path;
    TempDir() {
        std::random_device rd;
        path = std::filesystem::temp_directory_path() / ("dynbvh_test_bart_" + std::to_string(rd()) + std::to_string(rd()));
        std::filesystem::create_directories(path);
    }
    ~TempDir() { std::error_code ec; std::filesystem::remove_all(path, ec); }
    std::string write(const std::string& name, const std::string& text) const {
        const std::filesystem::path p = path / name;
        std::filesystem::create_directories(p.parent_path());
        std::ofstream(p, std::ios::binary) << text;
        return p.string();
    }
};

// One triangle at the origin of an animated transform: p0 = (0,0,0), p1 = (1,0,0), p2 = (0,1,0).
const char* const kUnitTriangle = "p 3  0 0 0  1 0 0  0 1 0\n";

} // namespace

// ---------------------------------------------------------------------------------------------
// Real scenes
// ---------------------------------------------------------------------------------------------

TEST_CASE("bart: triangle counts of Kitchen, Robots and Museum5") {
    const struct { const char* path; std::size_t triangles; std::size_t frames; } scenes[] = {
        {kKitchen, 110561, 800}, {kRobots, 71708, 800}, {kMuseum, 11308, 300}};
    for (const auto& sc : scenes) {
        CAPTURE(sc.path);
        const BartScene* s = real_scene(sc.path);
        if (!s) { MESSAGE("BART data absent, skipped: " << sc.path); continue; }
        CHECK(s->triangle_count() == sc.triangles);
        CHECK(s->frame_count() == sc.frames);
        const auto& st = s->stats();
        // cones are not triangles (BartOptions::tessellate_cones is off)
        CHECK(st.polygon_triangles + st.mesh_triangles + st.textured_triangles + st.animated_triangles == sc.triangles);
        CHECK(st.cone_triangles == 0);
        Frame f;
        const_cast<BartScene*>(s)->frame(0, f);
        REQUIRE(f.triangles.size() == sc.triangles);
        REQUIRE(f.material.size() == sc.triangles);
        std::size_t covered = 0;
        for (const auto& o : f.objects) {
            CHECK(o.first_triangle == covered);   // objects tile the frame in order
            covered += o.triangle_count;
        }
        CHECK(covered == sc.triangles);
        std::size_t finite = 0;
        for (const auto& t : f.triangles) finite += t.is_finite();
        CHECK(finite == sc.triangles);
        for (std::uint32_t m : f.material) REQUIRE(m < s->info().materials.size());
    }
    if (const BartScene* m = real_scene(kMuseum)) {
        CHECK(m->stats().cones == 8);
        CHECK(m->stats().animated_triangles == 1024);
        CHECK(m->info().motion == io::Motion::incoherent);
    }
}

TEST_CASE("bart: Kitchen frame 0 and later frames differ exactly where the animation says") {
    const BartScene* s = real_scene(kKitchen);
    if (!s) { MESSAGE("BART data absent, skipped: " << kKitchen); return; }
    Frame f0, f2, f10;
    s->evaluate(0.0, f0, exec::serial{});
    s->evaluate(2.0, f2, exec::serial{});    // the toy car's keys start at 3 s: nothing moved yet
    s->evaluate(10.0, f10, exec::serial{});  // the car drives through the kitchen, wheels spinning
    std::size_t statics = 0, animated = 0, moved = 0;
    for (std::size_t i = 0; i < f0.objects.size(); ++i) {
        const auto &o0 = f0.objects[i], &o2 = f2.objects[i], &o10 = f10.objects[i];
        CAPTURE(o0.name);
        REQUIRE(o0.first_triangle == o10.first_triangle);
        bool same2 = true, same10 = true;
        for (std::uint32_t k = o0.first_triangle; k < o0.first_triangle + o0.triangle_count; ++k) {
            same2 = same2 && same_bits(f0.triangles[k], f2.triangles[k]);
            same10 = same10 && same_bits(f0.triangles[k], f10.triangles[k]);
        }
        CHECK(same2);
        CHECK(o0.transform.m == o2.transform.m);
        if (!o0.animated) {
            ++statics;
            CHECK(same10);
            CHECK(o0.transform.m == o10.transform.m);
            continue;
        }
        ++animated;
        // triangles moved exactly when the object's transform changed
        CHECK(same10 == (o0.transform.m == o10.transform.m));
        moved += !same10;
        // ... and rigidly (no scale keys act before 19.75 s): edge lengths are kept
        for (std::uint32_t k = o0.first_triangle; k < o0.first_triangle + o0.triangle_count; ++k) {
            const Trianglef &a = f0.triangles[k], &b = f10.triangles[k];
            const float la = length(a.p1 - a.p0), lb = length(b.p1 - b.p0);
            REQUIRE(std::abs(la - lb) <= 1e-4f * std::max(1.0f, la));
        }
    }
    CHECK(statics > 0);
    CHECK(animated > 0);
    CHECK(moved == animated);   // every part of the car moves at 10 s
    CHECK(s->static_triangle_count() > 100000);
}

TEST_CASE("bart: Museum's animated triangles move, the room does not") {
    const BartScene* s = real_scene(kMuseum);
    if (!s) { MESSAGE("BART data absent, skipped: " << kMuseum); return; }
    Frame a, b;
    s->evaluate(0.0, a, exec::serial{});
    s->evaluate(2.5, b, exec::serial{});
    std::size_t moved_tpa = 0;
    for (const auto& o : a.objects) {
        CAPTURE(o.name);
        for (std::uint32_t k = o.first_triangle; k < o.first_triangle + o.triangle_count; ++k) {
            if (!o.animated) REQUIRE(same_bits(a.triangles[k], b.triangles[k]));
            else moved_tpa += !same_bits(a.triangles[k], b.triangles[k]);
        }
    }
    CHECK(moved_tpa > 900);   // of 1024 `tpa` triangles
}

TEST_CASE("bart: the camera follows its keyframes") {
    const BartScene* s = real_scene(kKitchen);
    if (!s) { MESSAGE("BART data absent, skipped: " << kKitchen); return; }
    Frame f0, f1;
    const_cast<BartScene*>(s)->frame(0, f0);
    const_cast<BartScene*>(s)->frame(400, f1);
    CHECK_FALSE(near(f0.camera.from, f1.camera.from, 1e-3f));
    // key 0.0 s of `k camera`: transl 3.75 2.3 3.6 (the key at -1 only shapes the tangent)
    CHECK(f0.camera.from == Vec3f{3.75f, 2.3f, 3.6f});
    // key 5.0 s: transl 3.5 0.2 0.1; rot -180 deg about (0,-1,0): looking along +z, y up
    const io::Camera c = s->camera_at(5.0);
    CHECK(near(c.from, {3.5f, 0.2f, 0.1f}));
    CHECK(near(normalize(c.at - c.from), {0, 0, 1}));
    CHECK(near(c.up, {0, 1, 0}));
    CHECK(c.fov_y_deg == 40.0f);
    CHECK(s->resolution() == std::array<int, 2>{800, 600});
    if (const BartScene* r = real_scene(kRobots)) {
        CHECK_FALSE(near(r->camera_at(0).from, r->camera_at(10).from, 1e-2f));
        CHECK(r->camera_at(0).from == Vec3f{-3.5f, 2.0f, -203.0f});
    }
}

TEST_CASE("bart: Kitchen materials reflect and refract") {
    const BartScene* s = real_scene(kKitchen);
    if (!s) { MESSAGE("BART data absent, skipped: " << kKitchen); return; }
    const auto& mats = s->info().materials;
    std::vector<bool> used(mats.size(), false);
    Frame f;
    s->evaluate(0, f, exec::serial{});
    for (std::uint32_t m : f.material) used[m] = true;
    bool glass = false, mirror = false;
    for (std::size_t i = 0; i < mats.size(); ++i) {
        if (!used[i]) continue;
        if (mats[i].transmission > 0) { glass = true; CHECK(mats[i].ior > 1.0f); }
        if (mats[i].specular.x > 0 || mats[i].specular.y > 0 || mats[i].specular.z > 0) mirror = true;
    }
    CHECK(glass);    // param_glass.aff: T 0.85, ior 1.55
    CHECK(mirror);
    CHECK(s->info().lights.size() == 6);
}

TEST_CASE("bart: update() reproduces evaluate() on the real scenes") {
    for (const char* path : {kKitchen, kRobots, kMuseum}) {
        const BartScene* s = real_scene(path);
        if (!s) { MESSAGE("BART data absent, skipped: " << path); continue; }
        CAPTURE(path);
        Frame inc, full;
        for (double t : {0.0, 4.0, 4.0, 7.5, 1.0, 12.25}) {
            s->update(t, inc);
            s->evaluate(t, full);
            REQUIRE(inc.triangles.size() == full.triangles.size());
            CHECK(std::memcmp(inc.triangles.data(), full.triangles.data(), full.triangles.size() * sizeof(Trianglef)) == 0);
            CHECK(inc.material == full.material);
            for (std::size_t i = 0; i < full.objects.size(); ++i) REQUIRE(inc.objects[i].transform.m == full.objects[i].transform.m);
        }
    }
}

// ---------------------------------------------------------------------------------------------
// Hand-written scenes with known answers
// ---------------------------------------------------------------------------------------------

TEST_CASE("bart: translation keys are interpolated exactly at the key times") {
    TempDir dir;
    const std::string path = dir.write("move.aff",
        "a 0 4 5\n"
        "x mover {\n" + std::string(kUnitTriangle) + "}\n"
        "k mover {\n"
        "  transl 6\n"
        "   -1   0 0 0    0 0 0\n"
        "    0   1 2 3    0.5 0 0\n"
        "    1   4 0 0    0 0.3 -0.2\n"
        "    2   4 4 0    0 0 0\n"
        "    3  -1 0 5    0 0 0\n"
        "    4   0 0 0    0 0 0\n"
        "}\n");
    auto s = io::load_bart(path);
    REQUIRE(s->triangle_count() == 1);
    REQUIRE(s->frame_count() == 5);
    const Vec3f keys[] = {{1, 2, 3}, {4, 0, 0}, {4, 4, 0}, {-1, 0, 5}};
    Frame f;
    for (int i = 0; i < 4; ++i) {
        CAPTURE(i);
        CHECK(s->frame_time(std::size_t(i)) == double(i));
        s->frame(std::size_t(i), f);
        CHECK(f.triangles[0].p0 == keys[i]);   // exact, not approximately
        CHECK(near(f.triangles[0].p1, keys[i] + Vec3f{1, 0, 0}));
        CHECK(f.objects[0].animated);
        CHECK(f.objects[0].transform.m[12] == keys[i].x);
    }
    // outside [key 1, key n-2] the curve is clamped (the end keys only shape tangents)
    s->evaluate(-0.5, f);
    CHECK(f.triangles[0].p0 == keys[0]);
    s->frame(4, f);
    CHECK(f.triangles[0].p0 == keys[3]);
    // between keys it is a curve, not a straight line (Catmull-Rom at the middle of 2 -> 3: all TCB 0 there)
    s->evaluate(2.5, f);
    const Vec3f p1 = keys[1], p2 = keys[2], p3 = keys[3], p4{0, 0, 0};
    const Vec3f cr = (p1 * -1.0f + p2 * 9.0f + p3 * 9.0f - p4) * (1.0f / 16.0f);
    CHECK(near(f.triangles[0].p0, cr, 1e-5f));
    CHECK_FALSE(near(f.triangles[0].p0, (p2 + p3) * 0.5f, 1e-2f));
}

TEST_CASE("bart: rotation, scale, static transforms and the hierarchy compose as T*R*S") {
    auto s = from_text(
        "a 0 3 4\n"
        "xs 2 2 2   0 0 1 90   1 0 0 {\n"          // p -> (1,0,0) + Rz90 * 2p
        "  x spin {\n" + std::string(kUnitTriangle) + "  }\n"
        "}\n"
        "k spin {\n"
        "  rot 5\n"
        "   0  0 0 2  0     0 0 0\n"             // axis need not be unit
        "   0  0 0 2  0     0 0 0\n"
        "   1  0 0 2  90    0 0 0\n"
        "   2  0 0 2  180   0 0 0\n"
        "   2  0 0 2  180   0 0 0\n"
        "  scale 4\n"
        "   0  1 1 1  0 0 0\n"
        "   0  1 1 1  0 0 0\n"
        "   3  3 1 1  0 0 0\n"
        "   3  3 1 1  0 0 0\n"
        "  transl 4\n"
        "   0  0 0 0  0 0 0\n"
        "   0  0 0 0  0 0 0\n"
        "   3  0 0 6  0 0 0\n"
        "   3  0 0 6  0 0 0\n"
        "}\n");
    REQUIRE(s->triangle_count() == 1);
    Frame f;
    // t = 0: identity animation: (1,0,0) -> 2*(1,0,0) = (2,0,0) -> Rz90 (0,2,0) -> + (1,0,0) = (1,2,0)
    s->evaluate(0, f);
    CHECK(near(f.triangles[0].p0, {1, 0, 0}));
    CHECK(near(f.triangles[0].p1, {1, 2, 0}));
    CHECK(near(f.triangles[0].p2, {-1, 0, 0}));
    // t = 3: scale (3,1,1), rotation 180 about z, translation (0,0,6): (1,0,0) -> (3,0,0) -> (-3,0,0) -> (-3,0,6);
    // then the static parent: 2*(-3,0,6) = (-6,0,12) -> Rz90 (0,-6,12) -> + (1,0,0)
    s->evaluate(3, f);
    CHECK(near(f.triangles[0].p0, {1, 0, 12}, 1e-4f));
    CHECK(near(f.triangles[0].p1, {1, -6, 12}, 1e-4f));
    // t = 1: rotation key 90 deg exactly (scale and translation are splines between their keys):
    // local x -> (sx,0,0) -> Rz90 (0,sx,0) -> parent x2, Rz90 -> (-2 sx, 0, 0); local y -> (0,-2,0)
    s->evaluate(1, f);
    const Vec3f o = f.triangles[0].p0, ex = f.triangles[0].p1 - o, ey = f.triangles[0].p2 - o;
    CHECK(near(ey, {0, -2, 0}, 1e-4f));
    CHECK(std::abs(ex.y) < 1e-4f);
    CHECK(std::abs(ex.z) < 1e-4f);
    CHECK(ex.x < -2.0f);   // sx > 1 on the way from scale 1 to 3
    CHECK(ex.x > -6.0f);
    // the rotation keys are hit exactly: RotationSpline returns the key quaternion
    io::bart::RotationSpline rot({{0, {0, 0, 1}, 0, 0, 0, 0}, {0, {0, 0, 1}, 0, 0, 0, 0}, {1, {0, 0, 1}, 1.5, 0.2, 0.1, -0.3},
                                  {2, {0, 0, 1}, 3.0, 0, 0, 0}, {2, {0, 0, 1}, 3.0, 0, 0, 0}});
    const io::bart::Quaternion q = rot(1.0);
    CHECK(q.w == doctest::Approx(std::cos(0.75)).epsilon(1e-12));
    CHECK(q.z == doctest::Approx(std::sin(0.75)).epsilon(1e-12));
    const io::bart::Quaternion qm = rot(1.5);
    CHECK(dot(qm, qm) == doctest::Approx(1.0).epsilon(1e-12));
    CHECK(qm.z > std::sin(0.75));
}

TEST_CASE("bart: camera keyframes, polygons, meshes, tpa, visibility, cones, materials, includes") {
    const std::map<std::string, std::string> files = {
        {"parts/mesh.aff",
         "fm 0.1 0.1 0.1  0.5 0.5 0.5  0.9 0.9 0.9  40 0.5 1.5\n"
         "m vertices 4  0 0 0  1 0 0  1 1 0  0 1 0\n"
         "  normals 1  0 0 1\n"
         "  texturecoords 2 t.ppm  0 0  1 1\n"
         "  triangles 2  0 1 2  0 0 0  0 1 1   0 2 3  0 0 0  0 1 0\n"
         "i 0 more.aff\n"},                         // relative to parts/
        {"parts/more.aff", "p 5  0 0 1  1 0 1  2 1 1  1 2 1  0 1 1\n"},
    };
    auto s = from_text(
        "v from 0 0 10 at 0 0 0 up 0 1 0 angle 45 hither 0.1 resolution 64 48\n"
        "l 1 2 3\n"
        "l 4 5 6  0.5 0.5 0.5\n"
        "a 0 2 3\n"
        "i 0 parts/mesh.aff\n"
        "i 1 parts/never.aff   # detail level 1 > 0: skipped, never opened\n"
        "fm 0.1 0.1 0.1  0.5 0.5 0.5  0.9 0.9 0.9  40 0.5 1.5   % same values: same material\n"
        "c 0 0 0 1  0 2 0 1\n"
        "tpa 2\n"
        "  0   0 0 0  0 0 1   1 0 0  0 0 1   0 1 0  0 0 1\n"
        "  2   2 0 0  0 0 1   3 0 0  0 0 1   2 1 0  0 0 1\n"
        "x blink {\n" + std::string(kUnitTriangle) + "}\n"
        "k blink { visibility 2  0.5 0  1.5 1 }\n"
        "k camera {\n"
        "  transl 4  0 0 0 5  0 0 0   0 0 0 5  0 0 0   2 5 0 0  0 0 0   2 5 0 0  0 0 0\n"
        "  rot 4     0 0 1 0 0  0 0 0   0 0 1 0 0  0 0 0   2 0 1 0 90  0 0 0   2 0 1 0 90  0 0 0\n"
        "}\n",
        files);
    // 2 mesh + 3 fan + 1 tpa + 1 blinking triangle; the cone is not triangulated
    REQUIRE(s->triangle_count() == 7);
    CHECK(s->stats().mesh_triangles == 2);
    CHECK(s->stats().polygon_triangles == 4);   // pentagon fan + the blinking triangle
    CHECK(s->stats().cones == 1);
    CHECK(s->stats().files == 3);
    CHECK(s->info().materials.size() == 2);   // the default plus one deduplicated `fm`
    CHECK(s->info().materials[1].transmission == 0.5f);
    CHECK(s->info().materials[1].ior == 1.5f);
    CHECK(s->info().lights.size() == 2);
    CHECK(s->info().lights[0].color == Vec3f{1, 1, 1});
    CHECK(s->info().lights[1].color == Vec3f{0.5f, 0.5f, 0.5f});
    CHECK(s->resolution() == std::array<int, 2>{64, 48});
    CHECK(s->static_triangle_count() == 5);

    Frame f;
    s->frame(0, f);
    // fan of the pentagon: (v0, v1, v2), (v0, v2, v3), (v0, v3, v4)
    bool fan = false;
    for (const auto& t : f.triangles) fan = fan || (t.p0 == Vec3f{0, 0, 1} && t.p1 == Vec3f{2, 1, 1} && t.p2 == Vec3f{1, 2, 1});
    CHECK(fan);
    for (std::size_t k = 0; k < 5; ++k) CHECK(f.material[k] == 1);
    // camera keys: t = 0 at (0,0,5) looking along -z, t = 2 at (5,0,0) turned 90 deg about y: looking along -x
    CHECK(f.camera.from == Vec3f{0, 0, 5});
    CHECK(near(f.camera.at - f.camera.from, {0, 0, -1}));
    s->frame(2, f);
    CHECK(near(f.camera.from, {5, 0, 0}));
    CHECK(near(f.camera.at - f.camera.from, {-1, 0, 0}));
    CHECK(near(f.camera.up, {0, 1, 0}));

    // tpa: linear between its keys at 0 and 2 s; the blinking triangle is NaN for 0.5 <= t < 1.5
    const auto find = [&](const char* tag) {
        for (const auto& o : f.objects)
            if (o.name.find(tag) != std::string::npos) return o;
        FAIL("no object " << tag);
        return f.objects[0];
    };
    s->evaluate(1.0, f);
    const auto tpa = find("animated triangles"), blink = find("[blink]");
    CHECK(tpa.animated);
    CHECK(tpa.rigid_body == io::no_rigid_body);   // vertex animation: it changes shape
    CHECK(blink.rigid_body != io::no_rigid_body);
    CHECK(near(f.triangles[tpa.first_triangle].p0, {1, 0, 0}));
    CHECK(near(f.triangles[tpa.first_triangle].p1, {2, 0, 0}));
    CHECK(std::isnan(f.triangles[blink.first_triangle].p0.x));
    s->evaluate(0.25, f);
    CHECK(f.triangles[blink.first_triangle].p1 == Vec3f{1, 0, 0});
    s->evaluate(1.5, f);
    CHECK(f.triangles[blink.first_triangle].p1 == Vec3f{1, 0, 0});
    s->evaluate(5.0, f);
    CHECK(f.triangles[tpa.first_triangle].p0 == Vec3f{2, 0, 0});

    // update() follows visibility and tpa changes
    Frame inc, full;
    for (double t : {0.0, 1.0, 1.0, 2.0, 0.7, 0.2}) {
        s->update(t, inc);
        s->evaluate(t, full);
        CHECK(std::memcmp(inc.triangles.data(), full.triangles.data(), full.triangles.size() * sizeof(Trianglef)) == 0);
    }

    // cones as triangles on request: 8 segments of 2 triangles
    auto tess = from_text("c 0 0 0 1  0 2 0 0.5\n", {}, BartOptions{.tessellate_cones = true, .cone_segments = 8});
    CHECK(tess->triangle_count() == 16);
    Frame tf;
    tess->frame(0, tf);
    for (const auto& t : tf.triangles) {
        for (const Vec3f& p : {t.p0, t.p1, t.p2}) {
            const float r = std::sqrt(p.x * p.x + p.z * p.z);
            CHECK(r == doctest::Approx(p.y == 0 ? 1.0f : 0.5f).epsilon(1e-5));
        }
    }
    // the BART frame rate can be overridden
    auto fps = from_text("a 1 3 5\n" + std::string(kUnitTriangle), {}, BartOptions{.fps = 10});
    CHECK(fps->frame_count() == 21);
    CHECK(fps->frame_time(20) == doctest::Approx(2.0));
}

// ---------------------------------------------------------------------------------------------
// Malformed input: a LoadError naming the file and the line, nothing else
// ---------------------------------------------------------------------------------------------

TEST_CASE("bart: malformed input gives LoadError with file and line") {
    const std::map<std::string, std::string> none;
    // missing include
    require_error("p 3 0 0 0 1 0 0 0 1 0\ni 0 nothere.aff\n", none, "main.aff", 2, "cannot open include");
    // cyclic includes (also through a subdirectory and back)
    require_error("i 0 main.aff\n", none, "main.aff", 1, "cyclic include");
    require_error("\ni 0 sub/a.aff\n", {{"sub/a.aff", "i 0 b.aff\n"}, {"sub/b.aff", "\n\ni 0 ../main.aff\n"}}, "sub/b.aff", 3,
                  "cyclic include: main.aff -> sub/a.aff -> sub/b.aff -> main.aff");
    // truncated files
    require_error("p 3 0 0 0 1 0 0 0 1 0\nxs 1 1 1\n0 0 1 90\n", none, "main.aff", 3, "unexpected end of file");
    require_error("m\nvertices 3\n0 0 0\n1 0 0\n0 1", none, "main.aff", 2, "more than the rest of the file can hold");
    require_error("xs 1 1 1 0 0 1 0 0 0 0\n{\np 3 0 0 0 1 0 0 0 1 0\n", none, "main.aff", 2, "never closed");
    require_error("k a {\n transl 4\n 0 0 0 0 0 0 0\n", none, "main.aff", 2, "is more than the rest of the file can hold");
    // unknown keywords
    require_error("\n\nq 1 2 3\n", none, "main.aff", 3, "unknown command 'q'");
    require_error("k a { spin 4 }\n", none, "main.aff", 1, "unknown keyframe track 'spin'");
    // indices out of range
    require_error("m vertices 3 0 0 0 1 0 0 0 1 0\n triangles 1\n 0 1 3\n", none, "main.aff", 3, "vertex index 3 is out of range");
    require_error("m vertices 3 0 0 0 1 0 0 0 1 0\n normals 1 0 0 1\n triangles 1\n 0 1 2 0 0 1\n", none, "main.aff", 4,
                  "normal index 1 is out of range");
    // NaN and infinite numbers
    require_error("p 3\n0 0 0\n1 nan 0\n0 1 0\n", none, "main.aff", 3, "not a finite number");
    require_error("p 3\n0 0 0\n1 0 0\n0 1 -inf\n", none, "main.aff", 4, "not a finite number");
    require_error("p 3 0 0 0 1 0 0 0 1e999 0\n", none, "main.aff", 1, "out of range");
    require_error("l 1 2 3 1 1 1e40\n", none, "main.aff", 1, "out of float range");
    // wrong counts: too many announced, too few announced, absurd, negative, below the minimum
    require_error("p 4\n0 0 0\n1 0 0\n0 1 0\np 3 0 0 0 1 0 0 0 1 0\n", none, "main.aff", 5, "expected polygon vertex coordinate, got 'p'");
    require_error("p 3\n0 0 0\n1 0 0\n0 1 0\n1 1 0\n", none, "main.aff", 5, "unexpected number '1'");
    require_error("m vertices 4000000000\n0 0 0\n", none, "main.aff", 1, "more than the rest of the file can hold");
    require_error("p -3 0 0 0\n", none, "main.aff", 1, "expected a count of polygon vertices, got '-3'");
    require_error("p 2 0 0 0 1 1 1\n", none, "main.aff", 1, "needs at least 3");
    require_error("k a {\n transl 3\n 0 0 0 0 0 0 0\n 1 0 0 0 0 0 0\n 2 0 0 0 0 0 0\n}\n", none, "main.aff", 2, "needs at least 4");
    require_error("tpa 2\n 1 0 0 0 0 0 1 1 0 0 0 0 1 0 1 0 0 0 1\n 0 0 0 0 0 0 1 1 0 0 0 0 1 0 1 0 0 0 1\n", none, "main.aff", 3,
                  "must not decrease");
    // structure
    require_error("p 3 0 0 0 1 0 0 0 1 0\n}\n", none, "main.aff", 2, "without a matching '{'");
    require_error("xs 1 1 1 0 0 1 0 0 0 0\np 3 0 0 0 1 0 0 0 1 0\n", none, "main.aff", 2, "expected '{' after the transform");
    require_error("x\n{\n}\n", none, "main.aff", 2, "expected a transform name");
    require_error("v from 0 0 1 angle 200\n", none, "main.aff", 1, "camera angle");
    require_error("a 5 1 10\n", none, "main.aff", 1, "before it starts");
    require_error("c 1 1 1 1 1 1 1 2\n", none, "main.aff", 1, "coincide");
    // an error inside an include names the included file and its own line
    require_error("i 0 a.aff\n", {{"a.aff", "p 3 0 0 0 1 0 0 0 1 0\n\n\nm vertices 1 0 0 0 triangles 1 0 0 7\n"}}, "a.aff", 4,
                  "out of range");
    // a '{' left open in an include is reported there, not silently closed by the includer
    require_error("xs 1 1 1 0 0 1 0 0 0 0 {\ni 0 a.aff\n}\n", {{"a.aff", "\nx t {\n"}}, "a.aff", 2, "never closed");
    // include bombs stop at the limits
    std::map<std::string, std::string> bomb;
    std::string ten;
    for (int k = 0; k < 10; ++k) ten += "i 0 b.aff\n";
    bomb["b.aff"] = std::string(kUnitTriangle) + "i 0 c.aff\ni 0 c.aff\n";
    bomb["c.aff"] = kUnitTriangle;
    require_error(ten, bomb, "b.aff", 2, "max_includes", BartOptions{.max_includes = 25});   // include #26
}

TEST_CASE("bart: missing files and files on disk") {
    try {
        (void)io::load_bart("/nonexistent/dir/scene.aff");
        FAIL("no LoadError");
    } catch (const LoadError& e) {
        CHECK(e.file() == "/nonexistent/dir/scene.aff");
        CHECK(std::string(e.what()).find("cannot open") != std::string::npos);
    }
    TempDir dir;
    dir.write("sub/part.aff", kUnitTriangle);
    dir.write("sub/loop.aff", "\ni 0 ../top.aff\n");
    const std::string top = dir.write("top.aff", "i 0 sub/part.aff\ni 0 ./sub/../sub/part.aff\n");
    CHECK(io::load_bart(top)->triangle_count() == 2);
    const std::string cyc = dir.write("cyc.aff", "i 0 sub/loop.aff\n");
    dir.write("top.aff", "i 0 cyc.aff\n");
    try {
        (void)io::load_bart(top);
        FAIL("no LoadError for a cyclic include");
    } catch (const LoadError& e) {
        CHECK(e.file().find("loop.aff") != std::string::npos);
        CHECK(e.where() == "line 2");
        CHECK(std::string(e.what()).find("cyclic include") != std::string::npos);
    }
}

TEST_CASE("bart: random corruption never crashes, it loads or throws LoadError") {
    const std::string good =
        "v from 0 0 10 at 0 0 0 up 0 1 0 angle 45 hither 0.1 resolution 64 48\n"
        "a 0 2 3\nfm 0.1 0.1 0.1 0.5 0.5 0.5 0.9 0.9 0.9 40 0.5 1.5\n"
        "xs 1 1 1 0 1 0 30 1 2 3 {\n x arm {\n"
        "  m vertices 4 0 0 0 1 0 0 1 1 0 0 1 0 normals 1 0 0 1 triangles 2 0 1 2 0 0 0 0 2 3 0 0 0\n"
        "  p 4 0 0 1 1 0 1 1 1 1 0 1 1\n }\n}\n"
        "k arm { transl 4 0 0 0 0 0 0 0 0 0 0 0 0 0 0 1 1 1 1 0 0 0 2 1 1 1 0 0 0\n"
        "        rot 4 0 0 1 0 0 0 0 0 0 0 1 0 0 0 0 0 1 0 1 0 90 0 0 0 2 0 1 0 90 0 0 0 }\n"
        "tpa 2 0 0 0 0 0 0 1 1 0 0 0 0 1 0 1 0 0 0 1 1 1 0 0 0 0 1 2 0 0 0 0 1 1 1 0 0 0 1\n"
        "i 0 inc.aff\n";
    const std::map<std::string, std::string> inc = {{"inc.aff", "c 0 0 0 1 0 1 0 1\np 3 0 0 0 1 0 0 0 1 0\n"}};
    REQUIRE(from_text(good, inc)->triangle_count() == 6);
    std::mt19937 rng(12345);
    const char alphabet[] = " \n{}#%-+.eE0123456789pmxk\0\xff";
    std::size_t loaded = 0, rejected = 0;
    for (int round = 0; round < 600; ++round) {
        std::string s = good;
        const int edits = 1 + int(rng() % 4);
        for (int e = 0; e < edits; ++e) {
            const std::size_t at = rng() % s.size();
            switch (rng() % 4) {
                case 0: s[at] = alphabet[rng() % (sizeof(alphabet) - 1)]; break;
                case 1: s.erase(at, 1 + rng() % 8); break;
                case 2: s.insert(at, 1, alphabet[rng() % (sizeof(alphabet) - 1)]); break;
                default: s.resize(at); break;   // truncation
            }
            if (s.empty()) s = "p";
        }
        try {
            auto sc = from_text(s, inc);
            Frame f;
            for (std::size_t i = 0; i < sc->frame_count() && i < 3; ++i) sc->frame(i, f);
            ++loaded;
        } catch (const LoadError& e) {
            REQUIRE(!e.file().empty());
            ++rejected;
        }
    }
    CHECK(loaded > 0);
    CHECK(rejected > 0);
}
