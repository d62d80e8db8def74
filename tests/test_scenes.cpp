// Built-in scenes: API, geometry helpers, determinism, truthful flags, materials, cameras,
// and the comparison with the real UNC frames (skipped when ../shared/data is absent).
#include <doctest/doctest.h>

#include <dynbvh/io/ply.hpp>
#include <render/material.hpp>
#include <scenes/builtin.hpp>

#include "sanitized.hpp"

#include <algorithm>
#include <cmath>
#include <cstring>
#include <filesystem>
#include <numbers>
#include <set>
#include <string>
#include <vector>

using namespace dynbvh;
using namespace dynbvh::scenes;

namespace {

AABBf bounds_of(const std::vector<Trianglef>& tris) {
    AABBf b;
    for (const Trianglef& t : tris) b.extend(t.bounds());
    return b;
}

/// Mean displacement of triangle corners from frame a to frame b, over a's bounding-box diagonal.
double relative_motion(const std::vector<Trianglef>& a, const std::vector<Trianglef>& b) {
    REQUIRE(a.size() == b.size());
    double sum = 0;
    for (std::size_t i = 0; i < a.size(); ++i)
        sum += double(length(b[i].p0 - a[i].p0)) + double(length(b[i].p1 - a[i].p1)) + double(length(b[i].p2 - a[i].p2));
    return sum / (3.0 * double(a.size())) / double(length(bounds_of(a).diagonal()));
}

bool same_triangles(const io::Frame& a, const io::Frame& b) {
    return a.triangles.size() == b.triangles.size() &&
           std::memcmp(a.triangles.data(), b.triangles.data(), a.triangles.size() * sizeof(Trianglef)) == 0 && a.material == b.material;
}

/// Normalised image coordinates of `p` seen by `c` (square image: |x|, |y| <= 1 is inside); z = depth.
Vec3f project(const io::Camera& c, Vec3f p) {
    const Vec3f fw = normalize(c.at - c.from), right = normalize(cross(fw, c.up)), up = cross(right, fw);
    const Vec3f d = p - c.from;
    const float z = dot(d, fw), t = std::tan(c.fov_y_deg * float(std::numbers::pi) / 360.0f);
    return {dot(d, right) / (z * t), dot(d, up) / (z * t), z};
}

/// Invariants every frame of every scene must satisfy.
void check_frame(const io::Scene& scene, const io::Frame& f) {
    const io::SceneInfo& info = scene.info();
    REQUIRE(!f.triangles.empty());
    REQUIRE(f.material.size() == f.triangles.size());
    bool finite = true, ids_ok = true;
    for (const Trianglef& t : f.triangles) finite = finite && t.is_finite();
    for (std::uint32_t m : f.material) ids_ok = ids_ok && m < info.materials.size();
    CHECK(finite);
    CHECK(ids_ok);
    // Objects: consecutive runs covering every triangle once.
    std::size_t next = 0;
    for (const io::ObjectInstance& o : f.objects) {
        CHECK(o.first_triangle == next);
        next = o.first_triangle + std::size_t(o.triangle_count);
    }
    CHECK(next == f.triangles.size());
    // The camera looks at the scene.
    const Vec3f q = project(f.camera, bounds_of(f.triangles).center());
    CHECK(q.z > 0);
    CHECK(std::fabs(q.x) < 0.5f);
    CHECK(std::fabs(q.y) < 0.5f);
    CHECK(f.camera.fov_y_deg > 0);
}

struct Expect {
    std::string_view name;
    std::size_t frames;
    io::Motion motion;
    bool topology_changes;
    double full_count;   // triangles of the UNC counterpart at frame 0
};
constexpr Expect expected[] = {{"cloth-ball", 94, io::Motion::incoherent, false, 92230},
                               {"n-body", 76, io::Motion::hierarchical, false, 146480},
                               {"breaking", 16, io::Motion::semi_hierarchical, true, 252000},
                               {"large-breaking", 45, io::Motion::semi_hierarchical, true, 1600000},
                               {"funnel", 150, io::Motion::incoherent, false, 18484}};

std::string data(const char* rel) { return std::string(DYNBVH_DATA_DIR) + "/" + rel; }

} // namespace

TEST_CASE("scenes: SplitMix64 matches the reference sequence") {
    SplitMix64 g(0);
    CHECK(g.next() == 0xE220A8397B1DCDAFull);
    CHECK(g.next() == 0x6E789E6AA1B965F4ull);
    CHECK(g.next() == 0x06C45D188009454Full);
    SplitMix64 h(1);
    for (int i = 0; i < 1000; ++i) {
        const double u = h.uniform();
        REQUIRE(u >= 0);
        REQUIRE(u < 1);
    }
}

TEST_CASE("scenes: geometry generators are closed, outward and the documented size") {
    const IndexedMesh s = uv_sphere({1, 2, 3}, 2, 20, 20);
    CHECK(s.faces.size() == 760);
    CHECK(s.vertices.size() == 382);
    for (const Vec3f& v : s.vertices) CHECK(length(v - Vec3f{1, 2, 3}) == doctest::Approx(2).epsilon(1e-5));
    CHECK(signed_volume(s) == doctest::Approx(4.0 / 3 * std::numbers::pi * 8).epsilon(0.03));
    CHECK(uv_sphere_triangles(16, 16) == 480);
    for (auto [tris, slices, stacks] : {std::array<std::uint32_t, 3>{480, 16, 16}, {760, 20, 20}, {1740, 30, 30}}) {
        const SphereResolution r = sphere_resolution(tris);
        CHECK(r.slices == slices);
        CHECK(r.stacks == stacks);
    }
    const IndexedMesh c = cylinder({0, 0, 0}, 1.5f, 6, 62, 3);
    CHECK(c.faces.size() == 496);
    CHECK(signed_volume(c) == doctest::Approx(std::numbers::pi * 2.25 * 6).epsilon(0.01));
    const IndexedMesh g = grid({0, 0, 0}, {2, 0, 0}, {0, 0, -3}, 4, 5);
    CHECK(g.faces.size() == 40);
    CHECK(g.vertices.size() == 30);
    for (const Face& f : g.faces) {
        const Trianglef t{g.vertices[f[0]], g.vertices[f[1]], g.vertices[f[2]]};
        CHECK(t.normal().y > 0);   // u x v = +y
    }
    // A closed counter-clockwise profile (a washer) revolves into a solid of positive volume.
    const std::array<std::array<float, 2>, 4> washer = {{{1, 0}, {2, 0}, {2, 1}, {1, 1}}};
    const IndexedMesh w = revolve({0, 0, 0}, washer, 256, true);
    CHECK(w.faces.size() == 2 * 256 * 4);
    CHECK(signed_volume(w) == doctest::Approx(std::numbers::pi * 3).epsilon(0.01));
    CHECK_THROWS_AS(uv_sphere({0, 0, 0}, 1, 2, 2), std::invalid_argument);
}

TEST_CASE("scenes: Catmull-Rom upsampling keeps the coarse points and reproduces planes") {
    const std::uint32_t n = 7;
    std::vector<Vec3f> coarse(n * n);
    for (std::uint32_t j = 0; j < n; ++j)
        for (std::uint32_t i = 0; i < n; ++i) coarse[j * n + i] = {float(i), 0.5f * float(i) + 2.0f * float(j), float(j * j % 5)};
    // 7 -> 13: every other fine point is a coarse point.
    GridUpsampler up(n, 13);
    std::vector<Vec3f> fine(13 * 13);
    up.apply(coarse, fine);
    for (std::uint32_t j = 0; j < n; ++j)
        for (std::uint32_t i = 0; i < n; ++i) {
            const Vec3f a = fine[(2 * j) * 13 + 2 * i], b = coarse[j * n + i];
            CHECK(length(a - b) < 1e-5f);
        }
    // Interior samples of the affine x and y components are exact.
    for (std::uint32_t j = 2; j + 2 < 13; ++j)
        for (std::uint32_t i = 2; i + 2 < 13; ++i) {
            CHECK(fine[j * 13 + i].x == doctest::Approx(0.5 * i).epsilon(1e-5));
            CHECK(fine[j * 13 + i].y == doctest::Approx(0.25 * i + 1.0 * j).epsilon(1e-5));
        }
    CHECK_THROWS_AS(GridUpsampler(1, 5), std::invalid_argument);
}

TEST_CASE("scenes: names, errors and options") {
    const auto names = builtin_names();
    REQUIRE(names.size() == std::size(expected));
    for (std::size_t i = 0; i < names.size(); ++i) CHECK(names[i] == expected[i].name);
    try {
        (void)make_builtin("cloth_ball");
        FAIL("an unknown name must throw");
    } catch (const std::invalid_argument& e) {
        const std::string msg = e.what();
        CHECK(msg.find("'cloth_ball'") != std::string::npos);
        for (std::string_view n : names) CHECK(msg.find(std::string(n)) != std::string::npos);
    }
    for (double bad : {0.0, -1.0, 17.0, std::nan("")})
        for (std::string_view n : names) CHECK_THROWS_AS((void)make_builtin(n, {.seed = 1, .scale = bad}), std::invalid_argument);
    auto s = make_builtin("n-body", {.seed = 3, .scale = 0.05});
    io::Frame f;
    CHECK_THROWS_AS(s->frame(s->frame_count(), f), std::out_of_range);
}

TEST_CASE("scenes: every scene at scale 0.1 is valid, deterministic, truthful and scaled") {
    for (const Expect& e : expected) {
        INFO("scene " << e.name);
        auto a = make_builtin(e.name, {.seed = 5, .scale = 0.1});
        auto b = make_builtin(e.name, {.seed = 5, .scale = 0.1});
        auto c = make_builtin(e.name, {.seed = 6, .scale = 0.1});
        const io::SceneInfo& info = a->info();
        CHECK(info.name == e.name);
        CHECK(a->frame_count() == e.frames);
        CHECK(info.motion == e.motion);
        CHECK(info.topology_changes == e.topology_changes);
        CHECK(!info.materials.empty());
        REQUIRE(!info.lights.empty());
        CHECK(is_finite(info.lights[0].position));

        // Every frame in order: valid; counts constant exactly when topology is kept.
        io::Frame f, g;
        std::set<std::size_t> counts;
        std::vector<std::size_t> per_frame;
        for (std::size_t i = 0; i < a->frame_count(); ++i) {
            a->frame(i, f);
            if (i == 0 || i + 1 == a->frame_count() || i % (test::sanitized() ? 21 : 7) == 0) check_frame(*a, f);
            counts.insert(f.triangles.size());
            per_frame.push_back(f.triangles.size());
            CHECK(f.time == doctest::Approx(double(i) / 30));
        }
        CHECK((counts.size() > 1) == e.topology_changes);
        // `scale` shrinks triangle counts proportionally.
        CHECK(double(per_frame.front()) == doctest::Approx(0.1 * e.full_count).epsilon(0.05));
        if (e.topology_changes) CHECK(per_frame.back() > per_frame.front());   // pieces appear

        // Same seed: identical frames, in any access order; another seed: other frames.
        for (std::size_t i : {std::size_t(0), a->frame_count() / 2, a->frame_count() - 1}) {
            a->frame(i, f);
            b->frame(i, g);
            CHECK(same_triangles(f, g));
            CHECK(f.camera.from == g.camera.from);
        }
        a->frame(a->frame_count() - 1, f);
        a->frame(1, f);
        b->frame(1, g);
        CHECK(same_triangles(f, g));
        c->frame(1, g);
        CHECK_FALSE(same_triangles(f, g));

        // Things move between frames, and the camera is animated.
        a->frame(2, g);
        CHECK(relative_motion(f.triangles, g.triangles) > 0);
        a->frame(a->frame_count() - 1, g);
        CHECK_FALSE(f.camera.from == g.camera.from);
    }
}

TEST_CASE("scenes: materials, lights and objects as each scene declares") {
    io::Frame f;
    {
        auto s = make_builtin("funnel", {.seed = 1, .scale = 0.1});
        s->frame(0, f);
        const auto& mats = s->info().materials;
        bool glass_used = false;
        for (std::uint32_t m : f.material)
            if (render::refracts(mats[m])) {
                glass_used = true;
                CHECK(mats[m].ior == doctest::Approx(1.5));
            }
        CHECK(glass_used);
    }
    {
        auto s = make_builtin("n-body", {.seed = 1, .scale = 0.1});
        s->frame(3, f);
        REQUIRE(f.objects.size() == 301);
        std::size_t animated = 0;
        for (const auto& o : f.objects) animated += o.animated ? 1 : 0;
        CHECK(animated == 300);
        // A ball's transform maps its unit template sphere onto its triangles: the centre is the translation.
        const io::ObjectInstance& ball = f.objects[7];
        AABBf b;
        for (std::uint32_t t = ball.first_triangle; t < ball.first_triangle + ball.triangle_count; ++t) b.extend(f.triangles[t].bounds());
        CHECK(length(b.center() - Vec3f{ball.transform.m[12], ball.transform.m[13], ball.transform.m[14]}) < 0.05f);
        for (const auto& m : s->info().materials) {
            CHECK(!render::refracts(m));
            CHECK(!render::reflects(m));   // primary rays only, as in the study
        }
    }
    {
        auto s = make_builtin("breaking", {.seed = 1, .scale = 0.1});
        const std::uint32_t fracture = 3;
        REQUIRE(s->info().materials.size() > fracture);
        CHECK(s->info().materials[fracture].name == "fracture");
        s->frame(0, f);
        CHECK(std::count(f.material.begin(), f.material.end(), fracture) == 0);
        CHECK(f.objects.size() == 3);   // blob, intact body, floor
        s->frame(s->frame_count() - 1, f);
        CHECK(std::count(f.material.begin(), f.material.end(), fracture) > 0);
        CHECK(f.objects.size() > 20);   // shards
    }
}

TEST_CASE("scenes: full-scale counts and motion against the real UNC frames") {
    struct Case {
        const char* scene;
        const char* real_a;
        const char* real_b;
        std::size_t frame;   // compare our frame -> frame + 1 with the real pair
        std::size_t reference_count;
    };
    if (test::sanitized()) {   // (full-scale simulations: minutes unoptimised; the optimised pass runs them, CI time)
        MESSAGE("sanitizer run: the full-scale scenes are left to the optimised run");
        return;
    }
    const Case cases[] = {{"cloth-ball", "unc/cloth_ball92.ply", "unc/cloth_ball93.ply", 92, 92230},
                          {"n-body", "unc/balls16_18.ply", "unc/balls16_19.ply", 18, 146480},
                          {"funnel", "unc/funnel_227.ply", "unc/funnel_228.ply", 0, 18484}};
    for (const Case& c : cases) {
        INFO("scene " << std::string(c.scene));
        auto s = make_builtin(c.scene);
        io::Frame a, b;
        s->frame(c.frame, a);
        s->frame(c.frame + 1, b);
        check_frame(*s, a);
        CHECK(double(a.triangles.size()) == doctest::Approx(double(c.reference_count)).epsilon(0.05));
        const double ours = relative_motion(a.triangles, b.triangles);
        const std::string pa = data(c.real_a), pb = data(c.real_b);
        if (!std::filesystem::exists(pa) || !std::filesystem::exists(pb)) {
            MESSAGE("skipping the comparison with " << pa << ": real data absent");
            continue;
        }
        const io::Mesh ra = io::read_ply(pa), rb = io::read_ply(pb);
        CHECK(ra.faces.size() == c.reference_count);
        CHECK(double(a.triangles.size()) == doctest::Approx(double(ra.faces.size())).epsilon(0.05));
        if (c.frame == 0) continue;   // funnel: counts only (frame counts differ from the real run)
        const double real = relative_motion(ra.triangles(), rb.triangles());
        MESSAGE(std::string(c.scene) << ": " << a.triangles.size() << " triangles (real " << ra.faces.size() << "), motion per frame "
                        << ours << " of the diagonal (real " << real << ", ratio " << ours / real << ")");
        CHECK(ours / real >= 1.0 / 3);
        CHECK(ours / real <= 3.0);
    }
    // Breaking at full scale: the UNC Dragon's 252k at the start, within 5 % all along.
    auto s = make_builtin("breaking");
    io::Frame f;
    for (std::size_t i : {std::size_t(0), s->frame_count() - 1}) {
        s->frame(i, f);
        CHECK(double(f.triangles.size()) == doctest::Approx(252000.0).epsilon(0.05));
    }
}
