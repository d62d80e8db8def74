// OBJ reader on tinyobjloader: the real dragon against an independent parse, MTL mapping,
// per-face materials, fan triangulation, and malformed files.
#include <doctest/doctest.h>

#include <dynbvh/io/frames.hpp>
#include <dynbvh/io/obj.hpp>

#include <array>
#include <cstdio>
#include <cstdlib>
#include <span>
#include <string>
#include <vector>
#include <filesystem>
#include <fstream>
#include <random>
#include <sstream>

using namespace dynbvh;
using namespace dynbvh::io;

namespace {

struct TempDir {
    std::filesystem::path path;
    TempDir() : path(std::filesystem::temp_directory_path() / ("dynbvh_test_obj_" + std::to_string(std::random_device{}()))) {
        std::filesystem::create_directories(path);
    }
    ~TempDir() { std::filesystem::remove_all(path); }
    std::string write(const std::string& name, const std::string& text) const {
        const auto p = path / name;
        std::ofstream(p, std::ios::binary) << text;
        return p.string();
    }
};

/// Reads `path`, which must fail with a LoadError naming it; returns the error.
LoadError obj_error(const std::string& path) {
    try {
        (void)read_obj(path);
    } catch (const LoadError& e) {
        CHECK(e.file() == path);
        CHECK(std::string(e.what()).find(path) != std::string::npos);
        return e;
    }
    FAIL("no LoadError for " << path);
    return LoadError("", "", "");
}
bool mentions(const LoadError& e, const std::string& what) { return std::string(e.what()).find(what) != std::string::npos; }
std::size_t obj_load_ok(const std::string& path) { return read_obj(path).vertices.size(); }

} // namespace

TEST_CASE("dragon_100k.obj: counts, bounds and faces match an independent parse") {
    const std::string path = DYNBVH_DATA_DIR "/meshes/dragon_100k.obj";
    if (!std::filesystem::exists(path)) {
        MESSAGE("skipped: " << path << " is absent");
        return;
    }
    std::string warnings;
    const Mesh m = read_obj(path, &warnings);
    CHECK(m.faces.size() == 100000);
    CHECK(m.vertices.size() == 50000);
    CHECK(warnings.find("dragon.mtl") != std::string::npos);  // its mtllib is not shipped: a warning, not an error
    CHECK(m.materials.empty());
    CHECK(m.face_material.empty());

    // independent: sscanf over `v` and `f` lines (the file uses plain "f a b c")
    std::ifstream in(path);
    std::string line;
    AABBd box;
    std::vector<std::array<std::uint32_t, 3>> faces;
    std::size_t verts = 0;
    while (std::getline(in, line)) {
        double x, y, z;
        unsigned a, b, c;
        if (std::sscanf(line.c_str(), "v %lf %lf %lf", &x, &y, &z) == 3) { box.extend(Vec3d{x, y, z}); ++verts; }
        else if (std::sscanf(line.c_str(), "f %u %u %u", &a, &b, &c) == 3) faces.push_back({a - 1, b - 1, c - 1});
    }
    CHECK(verts == m.vertices.size());
    CHECK(m.faces == faces);
    const AABBf b = m.bounds();
    // tinyobjloader's own number parser may differ from strtod in the last float bit
    for (int k = 0; k < 3; ++k) {
        CHECK(b.min[static_cast<std::size_t>(k)] == doctest::Approx(box.min[static_cast<std::size_t>(k)]).epsilon(1e-6));
        CHECK(b.max[static_cast<std::size_t>(k)] == doctest::Approx(box.max[static_cast<std::size_t>(k)]).epsilon(1e-6));
    }
}

TEST_CASE("MTL materials map to io::Material, one id per triangle") {
    TempDir dir;
    dir.write("m.mtl",
              "newmtl glass\nKa 0.1 0.2 0.3\nKd 0.4 0.5 0.6\nKs 0.7 0.8 0.9\nNs 96\nNi 1.5\nd 0.25\nillum 4\n"
              "newmtl red\nKd 1 0 0\nTr 0.75\nillum 2\nTf 1 1 1\n"  // Tr only: d = 1 - Tr; Tf ignored for illum 2
              "newmtl water\nKd 0 0 1\nNi 1.33\nTf 0.5 0.25 0.75\nillum 7\n"
              "newmtl opaque\nKd 0.5 0.5 0.5\nTf 1 1 1\nillum 2\n");
    const std::string obj = dir.write("scene.obj",
                                      "mtllib m.mtl\n"
                                      "v 0 0 0\nv 1 0 0\nv 1 1 0\nv 0 1 0\nv 0 0 1\n"
                                      "f 1 2 3\n"          // before any usemtl: default material
                                      "usemtl red\nf 1 2 3 4\n"  // quad: two triangles, both red
                                      "usemtl glass\nf 2 3 5\n"
                                      "usemtl nosuch\nf 3 4 5\n"  // unknown name: default material
                                      "usemtl water\nf -1 -2 -3\n");
    std::string warnings;
    const Mesh m = read_obj(obj, &warnings);
    REQUIRE(m.faces.size() == 6);
    REQUIRE(m.materials.size() == 5);  // 4 from the MTL + "default"
    CHECK(m.materials[4].name == "default");
    const std::vector<std::uint32_t> ids = {4, 1, 1, 0, 4, 2};
    CHECK(m.face_material == ids);
    const std::vector<std::array<std::uint32_t, 3>> faces = {{0, 1, 2}, {0, 1, 2}, {0, 2, 3}, {1, 2, 4}, {2, 3, 4}, {4, 3, 2}};
    CHECK(m.faces == faces);

    const Material& glass = m.materials[0];
    CHECK(glass.name == "glass");
    CHECK(glass.ambient == Vec3f{0.1f, 0.2f, 0.3f});
    CHECK(glass.diffuse == Vec3f{0.4f, 0.5f, 0.6f});
    CHECK(glass.specular == Vec3f{0.7f, 0.8f, 0.9f});
    CHECK(glass.shininess == 96.0f);
    CHECK(glass.ior == 1.5f);
    CHECK(glass.opacity == 0.25f);
    CHECK(glass.transmission == 0.75f);
    CHECK(glass.illum == 4);
    const Material& red = m.materials[1];
    CHECK(red.opacity == doctest::Approx(0.25));
    CHECK(red.transmission == doctest::Approx(0.75));
    const Material& water = m.materials[2];
    CHECK(water.opacity == 1.0f);
    CHECK(water.transmission == doctest::Approx(0.5));
    CHECK(water.ior == doctest::Approx(1.33));
    CHECK(water.illum == 7);
    const Material& opaque = m.materials[3];
    CHECK(opaque.transmission == 0.0f);
    CHECK(opaque.specular == Vec3f{0, 0, 0});
}

TEST_CASE("an OBJ without usemtl has no materials; polygons are fan-triangulated") {
    TempDir dir;
    const Mesh m = read_obj(dir.write("p.obj", "# pentagon\no thing\nv 0 0 0\nv 1 0 0\nv 2 1 0\nv 1 2 0\nv 0 1 0\n"
                                              "vn 0 0 1\nvt 0 0\nf 1/1/1 2/1/1 3/1/1 4/1/1 5/1/1\nl 1 2\n"));
    const std::vector<std::array<std::uint32_t, 3>> faces = {{0, 1, 2}, {0, 2, 3}, {0, 3, 4}};
    CHECK(m.faces == faces);
    CHECK(m.materials.empty());
    CHECK(m.face_material.empty());
    CHECK(m.vertices[2] == Vec3f{2, 1, 0});
}

TEST_CASE("malformed OBJ: LoadError naming the file (and the line where it can be known)") {
    TempDir dir;
    SUBCASE("missing file") { CHECK(mentions(obj_error((dir.path / "none.obj").string()), "no such file")); }
    SUBCASE("index out of range") {
        const LoadError e = obj_error(dir.write("a.obj", "v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n\nf 1 2 4\n"));
        CHECK(e.where() == "line 6");
        CHECK(mentions(e, "out of range"));
        CHECK(obj_error(dir.write("b.obj", "v 0 0 0\nv 1 0 0\nf 1 2 -3\nv 0 1 0\n")).where() == "line 3");
    }
    SUBCASE("zero index: tinyobjloader's error is surfaced") {
        const LoadError e = obj_error(dir.write("z.obj", "v 0 0 0\nv 1 0 0\nv 0 1 0\nf 0 1 2\n"));
        CHECK(mentions(e, "tinyobjloader"));
        CHECK(mentions(e, "line 4"));
    }
    SUBCASE("NaN, infinity, overflow, missing coordinates") {
        CHECK(obj_error(dir.write("n.obj", "v 0 0 0\nv nan 0 0\nv 0 1 0\nf 1 2 3\n")).where() == "line 2");
        CHECK(obj_error(dir.write("i.obj", "v 0 0 0\nv 1 0 0\n  v 0 -inf 0\nf 1 2 3\n")).where() == "line 3");
        CHECK(obj_error(dir.write("o.obj", "v 0 0 0\nv 1 0 0\nv 0 1e999 0\nf 1 2 3\n")).where() == "line 3");
        CHECK(obj_error(dir.write("m.obj", "v 0 0 0\nv 1 0\nv 0 1 0\nf 1 2 3\n")).where() == "line 2");
        CHECK(obj_error(dir.write("c.obj", "v 0 0 0\nv 1 0 0\nv 0 1 # 0\nf 1 2 3\n")).where() == "line 3");
    }
}

TEST_CASE("read_obj from memory") {
    const std::string text = "v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n";
    std::string warnings;
    const Mesh m = read_obj(std::span<const char>(text.data(), text.size()), "mem.obj", "", &warnings);
    CHECK(m.faces.size() == 1);
    const std::string bad = "v 0 0 0\nf 1 2 3\n";
    try {
        (void)read_obj(std::span<const char>(bad.data(), bad.size()), "mem.obj", "");
        FAIL("no error");
    } catch (const LoadError& e) {
        CHECK(e.file() == "mem.obj");
        CHECK(e.where() == "line 2");
    }
}

// ---- issue 16.4-7 and 15.6: input tinyobjloader would misread --------------------------------

namespace {
/// read_obj from memory; the LoadError (with file "t.obj") or a FAIL when it loads.
LoadError mem_error(const std::string& text) {
    try {
        (void)read_obj(std::span<const char>(text.data(), text.size()), "t.obj", "");
    } catch (const LoadError& e) {
        CHECK(e.file() == "t.obj");
        return e;
    }
    FAIL("no LoadError for: " << text);
    return LoadError("", "", "");
}
Mesh mem_load(const std::string& text) { return read_obj(std::span<const char>(text.data(), text.size()), "t.obj", ""); }
const std::string tri3 = "v 0 0 0\nv 1 0 0\nv 0 1 0\n";
} // namespace

TEST_CASE("OBJ face indices at or beyond 2^31, or before the first vertex, are errors on their line") {
    // Absolute, relative and texture/normal parts; values that wrap a 32- or 64-bit integer.
    for (const std::string idx : {"4294967299", "99999999999999999999", "2147483648", "-2147483649", "-4294967293",
                                  "18446744073709551619", "1/4294967299", "1//99999999999", "1/1/-4294967296"}) {
        CAPTURE(idx);
        const LoadError e = mem_error(tri3 + "f 1 2 3\n# comment\nf 1 2 " + idx + "\n");
        CHECK(e.where() == "line 6");
        CHECK(mentions(e, "out of range"));
    }
    // Relative indices reaching before the first vertex, counted at the face's line (the 4th vertex comes later).
    CHECK(mem_error(tri3 + "f -1 -2 -4\nv 0 0 1\n").where() == "line 4");
    CHECK(mem_error(tri3 + "f -1 -2 -4\nv 0 0 1\n").what() == std::string(mem_error(tri3 + "f -1 -2 -4\n").what()));
    // Below 2^31 but beyond the vertices: the existing range check, also on the line.
    CHECK(mem_error(tri3 + "f 1 2 2147483647\n").where() == "line 4");
    // Not wholly an integer.
    for (const std::string idx : {"3x", "3.0", "+-3", "3/x", "0x3", "/3", "1/2/3/4"}) {
        CAPTURE(idx);
        CHECK(mem_error(tri3 + "f 1 2 " + idx + "\n").where() == "line 4");
    }
    // Valid spellings still load: relative, signed, with texture/normal parts.
    const Mesh m = mem_load(tri3 + "vt 0 0\nvn 0 0 1\nf -3 -2 -1\nf +1/1/1 2//1 3/1\n");
    const std::vector<std::array<std::uint32_t, 3>> faces = {{0, 1, 2}, {0, 1, 2}};
    CHECK(m.faces == faces);
}

TEST_CASE("OBJ numbers that are not wholly numbers are errors naming file, line and text") {
    for (const std::string num : {"1,5", "1.0.5", "1e5e5", "1..0", "--1", "1e", "0x10", "1f", ".", "+", "1-", "inf", "-nan", "1e999"}) {
        CAPTURE(num);
        for (int pos = 0; pos < 3; ++pos) {   // in each coordinate
            std::string v = pos == 0 ? num + " 0 0" : pos == 1 ? "0 " + num + " 0" : "0 0 " + num;
            const LoadError e = mem_error("v 0 0 0\nv " + v + "\nv 0 1 0\nf 1 2 3\n");
            CHECK(e.where() == "line 2");
            CHECK(mentions(e, "'" + num + "'"));
            CHECK(mentions(e, "t.obj"));
        }
    }
    // Valid spellings keep their exact value (as strtod then float would give).
    for (const std::string num : {"+1.5", "-0.25", ".5", "1.", "1e-3", "1E+2", "-0", "123456789.125", "3.4e38"}) {
        CAPTURE(num);
        const Mesh m = mem_load("v " + num + " 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n");
        CHECK(m.vertices[0].x == static_cast<float>(std::strtod(num.c_str(), nullptr)));
    }
}

TEST_CASE("OBJ with a UTF-8 byte-order mark loads every line") {
    const std::string bom = "\xEF\xBB\xBF";
    const Mesh m = mem_load(bom + "v 9 9 9\n" + tri3 + "f 1 2 3\nf 2 3 4\n");
    REQUIRE(m.vertices.size() == 4);
    CHECK(m.vertices[0] == Vec3f{9, 9, 9});
    CHECK(m.faces.size() == 2);
    CHECK(mem_load(bom + "v 9 9 9\r\nv 1 0 0\r\nv 0 1 0\r\nf 1 2 3\r\n").vertices[0] == Vec3f{9, 9, 9});
    CHECK(mem_load(bom + "# comment first\n" + tri3 + "f 1 2 3\n").faces.size() == 1);
    // Line numbers are unchanged by the mark.
    CHECK(mem_error(bom + tri3 + "f 1 2 7\n").where() == "line 4");
    CHECK(mem_error(bom + "v 1,5 0 0\n").where() == "line 1");
    // Only a leading mark is skipped: one in the middle of a line is not a number.
    CHECK(mem_error(tri3 + "v " + bom + "1 0 0\n").where() == "line 4");
}

TEST_CASE("OBJ backslash line continuation joins lines; errors name the file's line") {
    Mesh m = mem_load("v 0 0 \\\n5\nv 1 0 0\nv 0 1 0\nf 1 \\\n2 \\\r\n 3\n");
    REQUIRE(m.vertices.size() == 3);
    CHECK(m.vertices[0] == Vec3f{0, 0, 5});
    REQUIRE(m.faces.size() == 1);
    CHECK(m.faces[0] == std::array<std::uint32_t, 3>{0, 1, 2});
    m = mem_load("v \\\n1 \\\n2 \\\n3\n" + tri3 + "f 1 2 3\n");
    CHECK(m.vertices[0] == Vec3f{1, 2, 3});
    CHECK(m.vertices.size() == 4);
    // The lines after a join keep their numbers in errors (the joined line reports its first line).
    CHECK(mem_error("v 0 0 \\\n0\nv 1 0 0\nv bad 0 0\n").where() == "line 4");
    CHECK(mem_error("v 0 0 \\\n0\nv 1 0 0\nv 0 1 0\nf 1 2 \\\n9\n").where() == "line 5");
    CHECK(mem_error(tri3 + "v 0 0 \\\r\n\\\n1,5\n").where() == "line 4");
    // A backslash not at the end of a line is not a continuation.
    CHECK(mem_error("v 0 0 \\ 5\nv 1 0 0\nv 0 1 0\n").where() == "line 1");
}

TEST_CASE("an OBJ with neither vertices nor faces, and a directory, are errors naming the path") {
    TempDir dir;
    for (const std::string text : {"", "hello\nthis is a text file renamed .obj\n", "# only comments\n\n", "o name\ng group\n"}) {
        CAPTURE(text);
        const LoadError e = obj_error(dir.write("text.obj", text));
        CHECK(mentions(e, "no vertices and no faces"));
    }
    CHECK(obj_load_ok(dir.write("points.obj", "v 0 0 0\nv 1 2 3\n")) == 2);   // a point cloud is fine
    CHECK(mentions(obj_error(dir.path.string()), "directory"));
    std::filesystem::create_directories(dir.path / "d.obj");
    CHECK(mentions(obj_error((dir.path / "d.obj").string()), "directory"));
    // read_mesh and the single-file scene say so too (not "unknown mesh format ''"), with or without
    // a mesh extension on the directory's name.
    for (const auto& p : {dir.path.string(), (dir.path / "d.obj").string(), dir.path.string() + "/"}) {
        CAPTURE(p);
        for (int which = 0; which < 2; ++which) {
            try {
                if (which == 0) (void)read_mesh(p);
                else (void)open_mesh_scene(p);
                FAIL("a directory was read as a mesh");
            } catch (const LoadError& e) {
                CHECK(e.file() == p);
                CHECK(mentions(e, "is a directory"));
            }
        }
    }
}
