// The README's C++ code, compiled and run. Every ```cpp block of README.md appears in this file
// verbatim (line by line, indentation and blank lines aside; `#include` lines anywhere in the file):
// ctest `readme_snippets_in_sync` (tools/check_readme_snippets.sh) fails otherwise, so the README
// cannot drift from the API. The test cases around each block check what the block computes.
#include <algorithm>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <random>
#include <span>
#include <stdexcept>
#include <string>
#include <vector>

#include <doctest/doctest.h>

#include <dynbvh/binned_sah.hpp>
#include <dynbvh/io/bart.hpp>
#include <dynbvh/io/frames.hpp>   // read_mesh, open_frames (link dynbvh::io)
#include <dynbvh/kbvh.hpp>
#include <dynbvh/lbvh.hpp>
#include <dynbvh/mesh.hpp>
#include <dynbvh/ploc.hpp>
#include <dynbvh/refit.hpp>
#include <dynbvh/sah.hpp>
#include <dynbvh/traverse.hpp>
#include <dynbvh/validate.hpp>
#include <dynbvh/wide.hpp>        // make_wide; intersect/occluded for wide trees

#if !defined(_OPENMP) || !defined(DYNBVH_WITH_TBB)
#error "readme_snippets.cpp needs OpenMP and oneTBB (tests/CMakeLists.txt builds it only with both)"
#endif

using namespace dynbvh;

namespace {

/// A wavy (n x n quads) grid in z = 0.2 sin(x + t) cos(y): one frame of a deforming sheet, 2 n^2 faces.
io::Mesh sheet(int n, double t) {
    io::Mesh m;
    for (int y = 0; y <= n; ++y)
        for (int x = 0; x <= n; ++x) {
            const double fx = 4.0 * x / n - 2, fy = 4.0 * y / n - 2;
            m.vertices.push_back({float(fx), float(fy), float(0.2 * std::sin(fx + t) * std::cos(fy))});
        }
    const auto id = [n](int x, int y) { return std::uint32_t(y * (n + 1) + x); };
    for (int y = 0; y < n; ++y)
        for (int x = 0; x < n; ++x) {
            m.faces.push_back({id(x, y), id(x + 1, y), id(x + 1, y + 1)});
            m.faces.push_back({id(x, y), id(x + 1, y + 1), id(x, y + 1)});
        }
    return m;
}

/// A temporary folder made the working directory, holding the files the README's snippets open:
/// bunny.ply (a 32 x 32 sheet), frames/cloth_000.ply ... cloth_003.ply (a deforming 24 x 24 sheet),
/// kitchen.aff (a tiny BART scene: a camera, a light, a triangle moving along x).
struct SnippetFiles {
    std::filesystem::path dir, old_cwd = std::filesystem::current_path();
    SnippetFiles() {
        std::random_device rd;
        dir = std::filesystem::temp_directory_path() / ("dynbvh_readme_" + std::to_string(rd()) + std::to_string(rd()));
        std::filesystem::create_directories(dir / "frames");
        std::filesystem::current_path(dir);
        io::write_ply("bunny.ply", sheet(32, 0));
        for (int f = 0; f < 4; ++f) {
            char name[64];
            std::snprintf(name, sizeof name, "frames/cloth_%03d.ply", f);
            io::write_ply(name, sheet(24, 0.3 * f));
        }
        std::ofstream("kitchen.aff") << "v from 0 0 10 at 0 0 0 up 0 1 0 angle 45 hither 0.1 resolution 64 48\n"
                                        "l 1 2 3\n"
                                        "a 0 2 3\n"
                                        "x mover {\np 3  0 0 0  1 0 0  0 1 0\n}\n"
                                        "k mover {\n  transl 4\n  -1 0 0 0  0 0 0\n  0 0 0 0  0 0 0\n  2 2 0 0  0 0 0\n  3 2 0 0  0 0 0\n}\n";
    }
    ~SnippetFiles() {
        std::error_code ec;
        std::filesystem::current_path(old_cwd, ec);
        std::filesystem::remove_all(dir, ec);
    }
};

/// The triangles of the first snippet: a 2 x 2 square in z = 0 around the origin (two triangles).
std::vector<Trianglef> this_frames_triangles() {
    return {{{-1, -1, 0}, {1, -1, 0}, {1, 1, 0}}, {{-1, -1, 0}, {1, 1, 0}, {-1, 1, 0}}};
}

/// "Your tracing" in the frame-loop snippets: rays from above every 0.25 units over the sheet, each
/// checked against brute force. Counts the rays traced.
std::size_t rays_checked = 0;
template <class Tree>
void render(const Tree& bvh, const io::Frame& frame) {
    for (float x = -1.875f; x < 2; x += 0.25f)
        for (float y = -1.875f; y < 2; y += 0.25f) {
            const Rayf ray{.org = {x, y, 5}, .dir = {0.01f, 0.02f, -1}};
            const Hitf got = intersect(bvh, frame.triangles, ray), want = brute_force_intersect(frame.triangles, ray);
            CHECK(bool(got));
            CHECK(got.t == want.t);
            ++rays_checked;
        }
}

/// Double-precision copies of `tris`.
std::vector<Triangled> to_double(std::span<const Trianglef> tris) {
    std::vector<Triangled> d;
    for (const auto& t : tris) d.push_back({Vec3d(t.p0), Vec3d(t.p1), Vec3d(t.p2)});
    return d;
}

} // namespace

TEST_CASE("README use: PLOC build, closest and any hit, SAH") {
    std::vector<dynbvh::Trianglef> tris = this_frames_triangles();
    auto bvh = dynbvh::ploc::build(tris, {.radius = 5}, dynbvh::exec::omp{});
    dynbvh::Rayf ray{.org = {0, 0, 10}, .dir = {0, 0, -1}};
    auto hit = dynbvh::intersect(bvh, tris, ray);          // closest hit: hit.t, hit.u, hit.v, hit.prim
    bool occ = dynbvh::occluded(bvh, tris, ray);           // any hit
    double c = dynbvh::sah_cost(bvh, {.ct = 3, .ci = 2});  // tree quality (lower is better)

    CHECK(hit.t == 10.0f);
    CHECK(hit.prim < 2);
    CHECK(occ);
    CHECK(c > 0);
}

TEST_CASE("README tour: a mesh, a frame sequence, BART") {
    SnippetFiles files;
    rays_checked = 0;
    {
        io::Mesh mesh = io::read_mesh("bunny.ply");              // .ply, or .obj (+ .mtl), by extension
        std::vector<Trianglef> tris = mesh.triangles();          // one per face, in face order
        auto bvh = lbvh::build(tris);

        CHECK(mesh.faces.size() == 2 * 32 * 32);
        CHECK(tris.size() == mesh.faces.size());
        CHECK(validate(bvh, tris).ok());
    }
    {
        auto scene = io::open_frames("frames/cloth_%03d.ply");   // or a directory, or one file
        io::Frame frame;                                         // reused: its buffers serve every frame
        for (std::size_t f = 0; f < scene->frame_count(); ++f) {
            scene->frame(f, frame);                              // loaded ahead on a background thread
            auto bvh = ploc::build(frame.triangles);
            render(bvh, frame);                                  // your tracing; bvh indexes frame.triangles
        }
        CHECK(scene->info().name == "cloth");
        CHECK(rays_checked == 4 * 16 * 16);
    }
    {
        auto kitchen = io::load_bart("kitchen.aff");             // the same Scene interface
        io::Frame frame;
        kitchen->frame(2, frame);                                // frame.triangles, .material, .camera
        std::vector<io::Light> lights = kitchen->lights_at(kitchen->frame_time(2));

        REQUIRE(frame.triangles.size() == 1);
        CHECK(frame.triangles[0].p0 == Vec3f{2, 0, 0});         // the key at t = 2 moves the triangle by 2 along x
        CHECK(frame.camera.from == Vec3f{0, 0, 10});
        REQUIRE(lights.size() == 1);
        CHECK(lights[0].position == Vec3f{1, 2, 3});
    }
}

namespace {
struct MyVertex {   // a vertex with attributes after the position
    Vec3f position;
    float u, v;
};
} // namespace

TEST_CASE("README tour: an indexed mesh read in place") {
    const io::Mesh source = sheet(8, 0);
    std::vector<Vec3f> vertices = source.vertices;
    std::vector<std::uint32_t> indices;
    for (const auto& f : source.faces) indices.insert(indices.end(), {f[0], f[1], f[2]});
    std::vector<MyVertex> buffer;
    for (const Vec3f& p : vertices) buffer.push_back({p, 0.5f, 0.25f});

    MeshView<float> view(vertices, indices);                 // your buffers, read in place: no copy
    MeshView<float> fat(buffer.data(), buffer.size(), sizeof(MyVertex), indices);   // strided, 16/32-bit indices
    auto tree = ploc::build(view);                           // the tree make_triangles' array gives, bit for bit
    refit(tree, view);                                       // after moving the vertices in place

    const auto flat = make_triangles<float, std::uint32_t>(vertices, indices);
    const auto want = ploc::build(flat);
    REQUIRE(tree.nodes.size() == want.nodes.size());
    for (std::size_t i = 0; i < want.nodes.size(); ++i) {
        CHECK(tree.nodes[i].min == want.nodes[i].min);
        CHECK(tree.nodes[i].max == want.nodes[i].max);
    }
    CHECK(std::vector<std::uint32_t>(tree.prim_ids.begin(), tree.prim_ids.end()) ==
          std::vector<std::uint32_t>(want.prim_ids.begin(), want.prim_ids.end()));
    REQUIRE(fat.size() == flat.size());
    for (std::size_t k = 0; k < flat.size(); ++k) CHECK(fat[k].p1 == flat[k].p1);
    for (Vec3f& p : vertices) p.z += 0.5f;                    // moved in place: the view sees it
    refit(tree, view);
    CHECK(tree.bounds().min.z == doctest::Approx(want.bounds().min.z + 0.5f));
    CHECK(validate(tree, make_triangles<float, std::uint32_t>(vertices, indices)).ok());
}

TEST_CASE("README tour: the builders and their Configs") {
    const std::vector<Trianglef> tris = sheet(16, 0).triangles();
    auto a = lbvh::build(tris);                                  // fastest build
    auto b = ploc::build(tris, {.radius = 16});                  // better tree, about radius x the work
    auto c = kbvh::build(tris, {.split = {.beta = 0.1f}});       // presplit long triangles, then PLOC
    auto d = binned_sah::build(tris, {.bins = 16});              // the quality reference
    auto e = lbvh::build(tris, {.leaves = {.max_leaf_size = 4}});
    auto f = ploc::build<Node<>, prim::copied>(tris);            // leaves keep a copy of their triangles

    CHECK(validate(a, tris).ok());
    CHECK(validate(b, tris).ok());
    CHECK(validate(c, tris, {.expect_single_reference = false}).ok());
    CHECK(validate(d, tris).ok());
    CHECK(validate(e, tris).ok());
    CHECK(validate(f, tris).ok());
    CHECK(f.leaf_triangles.size() == f.prim_ids.size());
    for (const auto& n : e.nodes) CHECK(n.count <= 4);
}

TEST_CASE("README tour: refit, or rebuild when the SAH has decayed") {
    SnippetFiles files;
    rays_checked = 0;
    auto scene = io::open_frames("frames/cloth_%03d.ply");
    io::Frame frame;
    scene->frame(0, frame);
    auto bvh = ploc::build(frame.triangles);
    double built = sah_cost(bvh);                                          // the fresh tree's quality
    for (std::size_t f = 1; f < scene->frame_count(); ++f) {
        scene->frame(f, frame);
        const bool same = bvh.primitive_count == frame.triangles.size();   // refit needs the same triangles
        if (same) refit(bvh, frame.triangles);                             // new boxes, same topology: O(n)
        if (!same || sah_cost(bvh) > 1.25 * built) {                       // 25 % worse: rebuild
            bvh = ploc::build(frame.triangles);
            built = sah_cost(bvh);
        }
        render(bvh, frame);                                                // your tracing
    }
    CHECK(validate(bvh, frame.triangles).ok());
    CHECK(rays_checked == 3 * 16 * 16);
    // A span that is not the one the tree was built over is refused, the tree untouched.
    const auto nodes_before = bvh.nodes;
    CHECK_THROWS_AS(refit(bvh, std::span<const Trianglef>(frame.triangles).first(10)), std::invalid_argument);
    CHECK(std::equal(nodes_before.begin(), nodes_before.end(), bvh.nodes.begin(), bvh.nodes.end(),
                     [](const Node<>& x, const Node<>& y) { return x.bounds() == y.bounds() && x.index == y.index && x.count == y.count; }));
}

TEST_CASE("README tour: wide trees, rays and hits") {
    const std::vector<Trianglef> tris = sheet(16, 0.5).triangles();
    auto bvh = ploc::build(tris);
    const Rayf ray{.org = {0.3f, 0.2f, 5}, .dir = {0, 0, -1}};
    const Hitf binary_hit = intersect(bvh, tris, ray);

    auto wide4 = make_wide(bvh);                   // 4-wide copy: bvh stays, to be refitted next frame
    auto wide8 = make_wide<8>(std::move(bvh));     // 8-wide, taking over bvh's leaves (bvh is left empty)
    Hitf hit = intersect(wide4, tris, ray);
    bool blocked = occluded(wide8, tris, ray);

    CHECK(bvh.empty());
    CHECK(hit.t == binary_hit.t);
    CHECK(intersect(wide8, tris, ray).t == hit.t);
    CHECK(blocked);

    Rayf camera_ray = ray;
    Vec3f light{3, 3, 3};
    bool lit = false;

    Hitf h = intersect(wide4, tris, camera_ray);                      // t in [tmin, tmax], in units of |dir|
    if (h) {
        const Trianglef& t = tris[h.prim];                            // your triangle, never a leaf slot
        Vec3f p = t.p0 * (1 - h.u - h.v) + t.p1 * h.u + t.p2 * h.v;   // = camera_ray.org + h.t * camera_ray.dir
        Rayf shadow{.org = p, .dir = light - p, .tmin = 1e-4f, .tmax = 1 - 1e-4f};  // t = 1 is the light
        lit = !occluded(wide4, tris, shadow);
    }

    REQUIRE(h);
    const Trianglef& t = tris[h.prim];
    const Vec3f hit_point = t.p0 * (1 - h.u - h.v) + t.p1 * h.u + t.p2 * h.v;
    const Vec3f expected = camera_ray.org + camera_ray.dir * h.t;
    CHECK(std::abs(hit_point.x - expected.x) < 1e-5f);
    CHECK(std::abs(hit_point.y - expected.y) < 1e-5f);
    CHECK(std::abs(hit_point.z - expected.z) < 1e-5f);
    CHECK(lit == !brute_force_occluded(tris, Rayf{.org = hit_point, .dir = light - hit_point, .tmin = 1e-4f, .tmax = 1 - 1e-4f}));
}

TEST_CASE("README tour: double precision") {
    const std::vector<Trianglef> tris = sheet(8, 0).triangles();
    std::vector<Triangled> dtris = to_double(tris);
    auto dbvh = lbvh::build(dtris);                                // Bvh<Node<double>>, from the triangles
    auto big = ploc::build<Node<double, std::uint64_t>>(dtris);    // 64-byte nodes, 64-bit indices
    Hit<double> dh = intersect(big, dtris, Ray<double>{.org = {0.3, 0.2, 5}, .dir = {0, 0, -1}});

    static_assert(std::is_same_v<decltype(dbvh), Bvh<Node<double>>>);
    static_assert(sizeof(decltype(big)::node_type) == 64);
    static_assert(sizeof(decltype(dbvh)::node_type) == 56);
    CHECK(validate(dbvh, dtris).ok());
    CHECK(validate(big, dtris).ok());
    REQUIRE(dh);
    CHECK(dh.t == brute_force_intersect(dtris, Ray<double>{.org = {0.3, 0.2, 5}, .dir = {0, 0, -1}}).t);
}

TEST_CASE("README tour: choosing threads") {
    const std::vector<Trianglef> tris = sheet(16, 0).triangles();
    auto s = lbvh::build(tris, {}, exec::serial{});              // the calling thread only
    auto o = lbvh::build(tris, {}, exec::omp{.threads = 4});     // OpenMP, 4 threads (0: OMP_NUM_THREADS or all)
    auto t = lbvh::build(tris, {}, exec::tbb{4});                // oneTBB, in a private arena of 4 threads
    refit(o, tris, exec::omp{.threads = 2});                     // so does everything that runs in parallel

    // The same tree on every executor and thread count.
    REQUIRE(s.nodes.size() == o.nodes.size());
    REQUIRE(s.nodes.size() == t.nodes.size());
    for (std::size_t i = 0; i < s.nodes.size(); ++i) {
        CHECK(s.nodes[i].bounds() == o.nodes[i].bounds());
        CHECK(s.nodes[i].bounds() == t.nodes[i].bounds());
    }
    CHECK(std::equal(s.prim_ids.begin(), s.prim_ids.end(), t.prim_ids.begin(), t.prim_ids.end()));
}

TEST_CASE("README tour: errors") {
    SnippetFiles files;
    std::string message;
    try {
        auto scene = io::open_frames("frames/lamp_%03d.ply");
    } catch (const io::LoadError& e) {                 // every loader: file, "line N" / "byte N", problem
        message = e.what();                            // "frames/lamp_%03d.ply: no file matches the frame pattern"
    }
    CHECK(message == "frames/lamp_%03d.ply: no file matches the frame pattern");

    // The table of the README's "Errors" section, row by row.
    std::ofstream("broken.ply") << "ply\nformat ascii 1.0\nelement vertex 1\nproperty float x\nproperty float y\nproperty float z\nend_header\n1 nan 2\n";
    CHECK_THROWS_AS(io::read_mesh("broken.ply"), io::LoadError);
    CHECK_THROWS_AS(io::read_mesh("frames"), io::LoadError);
    const std::vector<Trianglef> tris = sheet(4, 0).triangles();
    const std::span<const Trianglef> fewer = std::span<const Trianglef>(tris).first(5);
    auto bvh = lbvh::build(tris);
    const Rayf ray{.org = {0, 0, 5}, .dir = {0, 0, -1}};
    CHECK_THROWS_AS(intersect(bvh, fewer, ray), std::invalid_argument);
    CHECK_THROWS_AS(occluded(bvh, fewer, ray), std::invalid_argument);
    CHECK_THROWS_AS(intersect(make_wide(bvh), fewer, ray), std::invalid_argument);
    CHECK_THROWS_AS(refit(bvh, fewer), std::invalid_argument);
    CHECK_THROWS_AS(epo(bvh, fewer), std::invalid_argument);
    CHECK_THROWS_AS(lbvh::build(tris, {.morton_bits = 32}), std::invalid_argument);
    CHECK_THROWS_AS(ploc::build(tris, {.morton_bits = 16}), std::invalid_argument);
    CHECK_THROWS_AS(binned_sah::build(tris, {.bins = 1}), std::invalid_argument);
    CHECK_THROWS_AS(kbvh::build(tris, {.split = {.beta = -1}}), std::invalid_argument);
    const std::vector<Vec3f> vertices{{0, 0, 0}, {1, 0, 0}, {0, 1, 0}};
    const std::vector<std::uint32_t> bad_index{0, 1, 3}, two_indices{0, 1};
    CHECK_THROWS_AS((make_triangles<float, std::uint32_t>(vertices, bad_index)), std::out_of_range);
    CHECK_THROWS_AS((make_triangles<float, std::uint32_t>(vertices, two_indices)), std::invalid_argument);
    auto scene = io::open_frames("frames");
    io::Frame frame;
    CHECK_THROWS_AS(scene->frame(scene->frame_count(), frame), std::out_of_range);
    // Not errors: NaN/inf triangles are left out and counted, untraceable rays hit nothing.
    std::vector<Trianglef> with_nan = tris;
    with_nan[3].p1.y = std::nanf("");
    auto partial = lbvh::build(with_nan);
    CHECK(partial.excluded == 1);
    CHECK_FALSE(intersect(partial, with_nan, Rayf{.org = {0, 0, 5}, .dir = {0, 0, 0}}));
}
