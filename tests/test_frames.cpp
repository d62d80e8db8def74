// Frame sequences: directory and pattern specs, order, content, background prefetch
// (in order, random access, errors, shutdown mid-sequence), single-mesh scenes, camera.
#include <doctest/doctest.h>

#include <dynbvh/io/frames.hpp>

#include <cmath>
#include <filesystem>
#include <fstream>
#include <random>

using namespace dynbvh;
using namespace dynbvh::io;

namespace {

struct TempDir {
    std::filesystem::path path;
    TempDir() : path(std::filesystem::temp_directory_path() / ("dynbvh_test_frames_" + std::to_string(std::random_device{}()))) {
        std::filesystem::create_directories(path);
    }
    ~TempDir() { std::filesystem::remove_all(path); }
    std::string str(const std::string& name) const { return (path / name).string(); }
};

/// Frame k: a strip of `n` triangles shifted by k along x (so every frame is distinct).
Mesh frame_mesh(int k, std::size_t n = 4) {
    Mesh m;
    for (std::size_t i = 0; i < n + 2; ++i)
        m.vertices.push_back({static_cast<float>(k) * 10 + static_cast<float>(i), static_cast<float>(i % 2), static_cast<float>(k)});
    for (std::uint32_t i = 0; i < n; ++i) m.faces.push_back({i, i + 1, i + 2});
    return m;
}

void check_frame(const Frame& f, const Mesh& expected) {
    const auto tris = expected.triangles();
    REQUIRE(f.triangles.size() == tris.size());
    for (std::size_t i = 0; i < tris.size(); ++i) {
        CHECK(f.triangles[i].p0 == tris[i].p0);
        CHECK(f.triangles[i].p1 == tris[i].p1);
        CHECK(f.triangles[i].p2 == tris[i].p2);
    }
    REQUIRE(f.objects.size() == 1);
    CHECK(f.objects[0].triangle_count == tris.size());
}

} // namespace

TEST_CASE("natural order of frame names") {
    using detail::frames::natural_less;
    CHECK(natural_less("f2.ply", "f10.ply"));
    CHECK(!natural_less("f10.ply", "f2.ply"));
    CHECK(natural_less("a9b", "a10a"));
    CHECK(natural_less("x01", "x1a"));
    CHECK(natural_less("x1", "x01"));
    CHECK(!natural_less("x01", "x1"));
    CHECK(natural_less("f02.ply", "f2.ply") == false);
    CHECK(!natural_less("same", "same"));
    std::vector<std::string> v = {"c_10.ply", "c_9.ply", "b.ply", "c_100.ply", "c_1.ply"};
    std::sort(v.begin(), v.end(), natural_less);
    CHECK(v == std::vector<std::string>{"b.ply", "c_1.ply", "c_9.ply", "c_10.ply", "c_100.ply"});
}

TEST_CASE("a directory of 3 frames opens in natural order with the right content") {
    TempDir dir;
    // written out of order, named so that plain string order would be wrong
    write_ply(dir.str("f_10.ply"), frame_mesh(2), PlyEncoding::binary_big_endian);
    write_ply(dir.str("f_2.ply"), frame_mesh(1), PlyEncoding::ascii);
    write_ply(dir.str("f_1.ply"), frame_mesh(0));
    std::ofstream(dir.str("notes.txt")) << "not a frame";
    CHECK(list_frames(dir.path.string()) == std::vector<std::string>{dir.str("f_1.ply"), dir.str("f_2.ply"), dir.str("f_10.ply")});

    auto scene = open_frames(dir.path.string());
    const SceneInfo& info = scene->info();
    CHECK(info.frames == 3);
    CHECK(scene->frame_count() == 3);
    CHECK(info.name == dir.path.filename().string());
    CHECK(info.motion == Motion::incoherent);
    CHECK(!info.topology_changes);
    Frame f;
    for (int k = 0; k < 3; ++k) {
        scene->frame(static_cast<std::size_t>(k), f);
        check_frame(f, frame_mesh(k));
        CHECK(f.time == doctest::Approx(k / 30.0));
        CHECK(f.objects[0].animated);
    }
    // random access and repeats after the sequence was consumed
    for (int k : {1, 1, 0, 2, 0}) {
        scene->frame(static_cast<std::size_t>(k), f);
        check_frame(f, frame_mesh(k));
    }
    CHECK_THROWS_AS(scene->frame(3, f), std::out_of_range);
}

TEST_CASE("printf patterns: %03d, %d, the contiguous run from the first index, name") {
    TempDir dir;
    for (int k : {5, 6, 7, 9}) {
        char name[32];
        std::snprintf(name, sizeof name, "cloth_%03d.ply", k);
        write_ply(dir.str(name), frame_mesh(k));
    }
    write_ply(dir.str("cloth_8.ply"), frame_mesh(8));  // does not print as %03d
    const auto files = list_frames(dir.str("cloth_%03d.ply"));
    CHECK(files == std::vector<std::string>{dir.str("cloth_005.ply"), dir.str("cloth_006.ply"), dir.str("cloth_007.ply")});
    CHECK(list_frames(dir.str("cloth_%d.ply")) == std::vector<std::string>{dir.str("cloth_8.ply")});
    auto scene = open_frames(dir.str("cloth_%03d.ply"), {.prefetch = 1, .fps = 10, .motion = Motion::rigid});
    CHECK(scene->info().name == "cloth");
    CHECK(scene->info().motion == Motion::rigid);
    Frame f;
    for (int k = 0; k < 3; ++k) {
        scene->frame(static_cast<std::size_t>(k), f);
        check_frame(f, frame_mesh(5 + k));
        CHECK(f.time == doctest::Approx(k / 10.0));
    }
    CHECK_THROWS_AS((void)list_frames(dir.str("nothing_%d.ply")), LoadError);
    CHECK_THROWS_AS((void)list_frames(dir.str("c_%d_%d.ply")), LoadError);
    CHECK_THROWS_AS((void)list_frames(dir.str("c_%s.ply")), LoadError);
    CHECK_THROWS_AS((void)list_frames(dir.str("missing_dir")), LoadError);
    CHECK_THROWS_AS((void)open_frames((dir.path / "empty").string()), LoadError);
}

TEST_CASE("topology change and materials are detected from the first and last frame") {
    TempDir dir;
    write_ply(dir.str("t0.ply"), frame_mesh(0, 4));
    write_ply(dir.str("t1.ply"), frame_mesh(1, 4));
    write_ply(dir.str("t2.ply"), frame_mesh(2, 6));
    auto scene = open_frames(dir.str("t%d.ply"));
    CHECK(scene->info().topology_changes);
    Frame f;
    scene->frame(2, f);
    CHECK(f.triangles.size() == 6);

    TempDir objs;
    std::ofstream(objs.str("m.mtl")) << "newmtl a\nKd 1 0 0\nnewmtl b\nKd 0 1 0\n";
    for (int k = 0; k < 2; ++k)
        std::ofstream(objs.str("o" + std::to_string(k) + ".obj"))
            << "mtllib m.mtl\nv " << k << " 0 0\nv 1 0 0\nv 0 1 0\nv 1 1 0\nusemtl b\nf 1 2 3\nusemtl a\nf 2 4 3\n";
    auto os = open_frames(objs.path.string());
    REQUIRE(os->info().materials.size() == 2);
    CHECK(os->info().materials[1].diffuse == Vec3f{0, 1, 0});
    CHECK(!os->info().topology_changes);
    os->frame(1, f);
    CHECK(f.material == std::vector<std::uint32_t>{1, 0});
    CHECK(f.triangles[0].p0 == Vec3f{1, 0, 0});
}

TEST_CASE("a bad frame throws its LoadError from frame(i); the others still load") {
    TempDir dir;
    write_ply(dir.str("s0.ply"), frame_mesh(0));
    std::ofstream(dir.str("s1.ply")) << "ply\nformat ascii 1.0\nelement vertex 1\nproperty float x\n";  // no end_header
    write_ply(dir.str("s2.ply"), frame_mesh(2));
    for (std::size_t prefetch : {0u, 2u}) {
        auto scene = open_frames(dir.str("s%d.ply"), {.prefetch = prefetch});
        Frame f;
        scene->frame(0, f);
        try {
            scene->frame(1, f);
            FAIL("frame 1 loaded");
        } catch (const LoadError& e) {
            CHECK(e.file() == dir.str("s1.ply"));
        }
        scene->frame(2, f);
        check_frame(f, frame_mesh(2));
    }
}

TEST_CASE("prefetch off (synchronous) gives the same frames") {
    TempDir dir;
    for (int k = 0; k < 4; ++k) write_ply(dir.str("p" + std::to_string(k) + ".ply"), frame_mesh(k));
    auto scene = open_frames(dir.path.string(), {.prefetch = 0});
    Frame f;
    for (int k : {0, 1, 3, 2}) {
        scene->frame(static_cast<std::size_t>(k), f);
        check_frame(f, frame_mesh(k));
    }
}

TEST_CASE("the prefetch thread shuts down cleanly when the scene is destroyed mid-sequence") {
    TempDir dir;
    for (int k = 0; k < 8; ++k) write_ply(dir.str("d" + std::to_string(k) + ".ply"), frame_mesh(k, 2000));
    for (std::size_t prefetch : {1u, 2u, 5u}) {
        for (int stop_after = 0; stop_after < 4; ++stop_after) {
            auto scene = open_frames(dir.path.string(), {.prefetch = prefetch});
            Frame f;
            for (int k = 0; k < stop_after; ++k) {
                scene->frame(static_cast<std::size_t>(k), f);
                check_frame(f, frame_mesh(k, 2000));
            }
            scene.reset();  // the loader may be mid-file: must stop and join, not hang or crash
        }
    }
    CHECK(true);
}

TEST_CASE("single mesh scene") {
    TempDir dir;
    write_ply(dir.str("one.ply"), frame_mesh(3));
    std::vector<std::unique_ptr<Scene>> scenes;
    scenes.push_back(open_mesh_scene(dir.str("one.ply")));
    scenes.push_back(open_frames(dir.str("one.ply")));
    for (auto& scene : scenes) {
        CHECK(scene->info().frames == 1);
        CHECK(scene->info().motion == Motion::none);
        CHECK(scene->info().name == "one");
        Frame f;
        scene->frame(0, f);
        check_frame(f, frame_mesh(3));
        CHECK(!f.objects[0].animated);
        CHECK_THROWS_AS(scene->frame(1, f), std::out_of_range);
    }
    CHECK_THROWS_AS((void)open_mesh_scene(dir.str("one.stl")), LoadError);
}

TEST_CASE("frame_bounds_camera sees the whole box") {
    const AABBf box{{-3, 1, 2}, {5, 2, 10}};
    const Camera c = frame_bounds_camera(box);
    CHECK(c.at == box.center());
    CHECK(c.fov_y_deg == 45.0f);
    CHECK(c.from.y > c.at.y);
    CHECK(c.from.z > c.at.z);
    const Vec3f view = normalize(c.at - c.from);
    const float half = 0.5f * c.fov_y_deg * 3.14159265f / 180.0f;
    for (int i = 0; i < 8; ++i) {
        const Vec3f corner{(i & 1) ? box.max.x : box.min.x, (i & 2) ? box.max.y : box.min.y, (i & 4) ? box.max.z : box.min.z};
        const float angle = std::acos(std::min(1.0f, dot(normalize(corner - c.from), view)));
        CHECK(angle <= half + 1e-5f);
    }
    const Camera d = frame_bounds_camera(AABBf::empty());
    CHECK(d.from == Camera{}.from);
    const Camera p = frame_bounds_camera(AABBf{{1, 1, 1}, {1, 1, 1}});  // a point: still a valid camera
    CHECK(length(p.from - p.at) > 0);
}

TEST_CASE("UNC pattern cloth_ball%d.ply: frames 92 and 93") {
    const std::string spec = DYNBVH_DATA_DIR "/unc/cloth_ball%d.ply";
    if (!std::filesystem::exists(DYNBVH_DATA_DIR "/unc/cloth_ball92.ply")) {
        MESSAGE("skipped: UNC data absent");
        return;
    }
    auto scene = open_frames(spec);
    CHECK(scene->info().name == "cloth_ball");
    CHECK(scene->info().frames == 2);
    CHECK(!scene->info().topology_changes);
    Frame f;
    scene->frame(1, f);
    CHECK(f.triangles.size() == 92230);
    const auto expected = read_ply(std::string(DYNBVH_DATA_DIR "/unc/cloth_ball93.ply")).triangles();
    REQUIRE(f.triangles.size() == expected.size());
    CHECK(std::equal(f.triangles.begin(), f.triangles.end(), expected.begin(), [](const Trianglef& a, const Trianglef& b) {
        return a.p0 == b.p0 && a.p1 == b.p1 && a.p2 == b.p2;
    }));
}
