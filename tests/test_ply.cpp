// PLY reader/writer: real files against an independent iostream reader, round trips in every
// encoding, every property type, fan triangulation, and every kind of malformed input.
#include <doctest/doctest.h>

#include <dynbvh/io/ply.hpp>

#include <algorithm>
#include <bit>
#include <cmath>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <limits>
#include <random>
#include <sstream>

using namespace dynbvh;
using namespace dynbvh::io;

namespace {

// ---- an independent, deliberately simple reader for the real files ------------------------
// getline + istringstream header, byte-by-byte reads with std::reverse for big-endian,
// operator>> for ascii. Knows only what the real files use.
struct SimplePly {
    std::vector<Vec3f> vertices;
    std::vector<std::array<std::uint32_t, 3>> faces;
    std::size_t polygons = 0;
};

std::size_t simple_size(const std::string& t) {
    if (t == "char" || t == "uchar") return 1;
    if (t == "short" || t == "ushort") return 2;
    if (t == "double") return 8;
    return 4;
}

template <class T> T simple_get(std::istream& in, bool big) {
    unsigned char b[sizeof(T)];
    in.read(reinterpret_cast<char*>(b), sizeof(T));
    if (big) std::reverse(b, b + sizeof(T));
    T v;
    std::memcpy(&v, b, sizeof(T));
    return v;
}

SimplePly simple_read(const std::string& path) {
    std::ifstream in(path, std::ios::binary);
    std::string line, format;
    struct Prop { std::string type, name; bool list = false; };
    struct Elem { std::string name; std::size_t n = 0; std::vector<Prop> props; };
    std::vector<Elem> elems;
    while (std::getline(in, line)) {
        std::istringstream ss(line);
        std::string k;
        ss >> k;
        if (k == "format") ss >> format;
        else if (k == "element") { elems.emplace_back(); ss >> elems.back().name >> elems.back().n; }
        else if (k == "property") {
            Prop p;
            ss >> p.type;
            if (p.type == "list") { p.list = true; std::string ct; ss >> ct >> p.type; REQUIRE(ct == "uchar"); }
            ss >> p.name;
            elems.back().props.push_back(p);
        } else if (k == "end_header") break;
    }
    SimplePly out;
    const bool ascii = format == "ascii", big = format == "binary_big_endian";
    for (const Elem& e : elems) {
        for (std::size_t i = 0; i < e.n; ++i) {
            float xyz[3] = {0, 0, 0};
            for (const Prop& p : e.props) {
                if (p.list) {
                    unsigned count = 0;
                    std::vector<std::uint32_t> idx;
                    if (ascii) in >> count;
                    else count = simple_get<unsigned char>(in, big);
                    for (unsigned k = 0; k < count; ++k) {
                        std::int64_t v = 0;
                        if (ascii) in >> v;
                        else v = simple_get<std::int32_t>(in, big);
                        idx.push_back(static_cast<std::uint32_t>(v));
                    }
                    ++out.polygons;
                    for (unsigned k = 2; k < count; ++k) out.faces.push_back({idx[0], idx[k - 1], idx[k]});
                    continue;
                }
                double v = 0;
                if (ascii) {
                    std::string tok;
                    in >> tok;
                    v = p.type == "float" ? double(std::stof(tok)) : std::stod(tok);
                } else if (p.type == "float") v = simple_get<float>(in, big);
                else if (p.type == "double") v = simple_get<double>(in, big);
                else in.ignore(static_cast<std::streamsize>(simple_size(p.type)));
                if (p.name == "x") xyz[0] = static_cast<float>(v);
                if (p.name == "y") xyz[1] = static_cast<float>(v);
                if (p.name == "z") xyz[2] = static_cast<float>(v);
            }
            if (e.name == "vertex") out.vertices.push_back({xyz[0], xyz[1], xyz[2]});
        }
    }
    REQUIRE(in.good());
    return out;
}

bool same_bits(const std::vector<Vec3f>& a, const std::vector<Vec3f>& b) {
    return a.size() == b.size() && std::memcmp(a.data(), b.data(), a.size() * sizeof(Vec3f)) == 0;
}

void check_real_file(const std::string& path, std::size_t vertices, std::size_t triangles) {
    if (!std::filesystem::exists(path)) {
        MESSAGE("skipped: " << path << " is absent");
        return;
    }
    const Mesh m = read_ply(path);
    CHECK(m.vertices.size() == vertices);
    CHECK(m.faces.size() == triangles);
    CHECK(m.face_material.empty());
    const SimplePly ref = simple_read(path);
    CHECK(ref.polygons == triangles);  // every face of these files is a triangle
    AABBf ref_box;
    for (const auto& v : ref.vertices) ref_box.extend(v);
    CHECK(m.bounds() == ref_box);
    CHECK(same_bits(m.vertices, ref.vertices));
    CHECK(m.faces == ref.faces);
}

// ---- building test files ------------------------------------------------------------------
struct Bytes {
    std::string s;
    bool big = false;
    template <class T> Bytes& put(T v) {
        char b[sizeof(T)];
        std::memcpy(b, &v, sizeof(T));
        if (big != (std::endian::native == std::endian::big)) std::reverse(b, b + sizeof(T));
        s.append(b, sizeof(T));
        return *this;
    }
    Bytes& text(const std::string& t) { s += t; return *this; }
};

Mesh parse(const std::string& bytes, const std::string& name = "test.ply") {
    return read_ply(std::span<const char>(bytes.data(), bytes.size()), name);
}

/// Parses `bytes`, which must fail; returns the error for further checks.
LoadError parse_error(const std::string& bytes, const std::string& name = "bad.ply") {
    try {
        (void)parse(bytes, name);
    } catch (const LoadError& e) {
        CHECK(e.file() == name);
        CHECK(std::string(e.what()).find(name) != std::string::npos);
        const bool located = e.where().rfind("line ", 0) == 0 || e.where().rfind("byte ", 0) == 0;
        CHECK_MESSAGE(located, std::string(e.what()));
        return e;
    }
    FAIL("no LoadError for:\n" << bytes.substr(0, 400));
    return LoadError("", "", "");
}

bool mentions(const LoadError& e, const std::string& what) { return std::string(e.what()).find(what) != std::string::npos; }

Mesh random_mesh(std::size_t nv, std::size_t nf, unsigned seed) {
    std::mt19937 rng(seed);
    std::uniform_real_distribution<float> coord(-1e3f, 1e3f);
    Mesh m;
    for (std::size_t i = 0; i < nv; ++i) m.vertices.push_back({coord(rng), coord(rng), coord(rng)});
    // values that stress float printing/parsing
    const float special[] = {0.0f, -0.0f, 1e-40f /*subnormal*/, std::numeric_limits<float>::denorm_min(),
                             std::numeric_limits<float>::max(), -std::numeric_limits<float>::max(),
                             std::numeric_limits<float>::min(), 0.1f, 1.0f / 3.0f, 16777217.0f, 3.4028233e38f, -1.17549435e-38f};
    for (std::size_t i = 0; i + 2 < std::size(special); i += 3) m.vertices.push_back({special[i], special[i + 1], special[i + 2]});
    std::uniform_int_distribution<std::uint32_t> idx(0, static_cast<std::uint32_t>(m.vertices.size() - 1));
    for (std::size_t f = 0; f < nf; ++f) m.faces.push_back({idx(rng), idx(rng), idx(rng)});
    return m;
}

std::filesystem::path temp_dir(const std::string& name) {
    auto d = std::filesystem::temp_directory_path() / ("dynbvh_test_ply_" + name + "_" + std::to_string(std::random_device{}()));
    std::filesystem::remove_all(d);
    std::filesystem::create_directories(d);
    return d;
}

constexpr PlyEncoding encodings[] = {PlyEncoding::ascii, PlyEncoding::binary_little_endian, PlyEncoding::binary_big_endian};

} // namespace

TEST_CASE("real PLY files: counts, bounds and every value match an independent reader") {
    check_real_file(DYNBVH_DATA_DIR "/unc/cloth_ball92.ply", 46598, 92230);  // BE float, list uchar int
    check_real_file(DYNBVH_DATA_DIR "/unc/balls16_18.ply", 73960, 146480);   // BE float + uchar rgb
    check_real_file(DYNBVH_DATA_DIR "/unc/funnel_227.ply", 9450, 18484);     // LE double xyz
    check_real_file(DYNBVH_DATA_DIR "/meshes/bun_zipper.ply", 35947, 69451); // ascii + confidence, intensity
}

TEST_CASE("a mesh written as PLY in each encoding reads back bit-exact") {
    const Mesh m = random_mesh(500, 900, 7);
    const auto dir = temp_dir("roundtrip");
    for (PlyEncoding enc : encodings) {
        CAPTURE(static_cast<int>(enc));
        const Mesh a = parse(to_ply(m, enc));
        CHECK(same_bits(a.vertices, m.vertices));
        CHECK(a.faces == m.faces);
        const std::string path = (dir / ("m" + std::to_string(static_cast<int>(enc)) + ".ply")).string();
        write_ply(path, m, enc);
        const Mesh b = read_ply(path);
        CHECK(same_bits(b.vertices, m.vertices));
        CHECK(b.faces == m.faces);
    }
    // the encodings really differ
    CHECK(to_ply(m, PlyEncoding::binary_little_endian) != to_ply(m, PlyEncoding::binary_big_endian));
    const Mesh empty;
    for (PlyEncoding enc : encodings) {
        const Mesh e = parse(to_ply(empty, enc));
        CHECK(e.vertices.empty());
        CHECK(e.faces.empty());
    }
    std::filesystem::remove_all(dir);
}

TEST_CASE("writer rejects what the reader would reject") {
    Mesh m = random_mesh(4, 2, 1);
    m.faces.push_back({0, 1, static_cast<std::uint32_t>(m.vertices.size())});
    CHECK_THROWS_AS((void)to_ply(m), std::invalid_argument);
    Mesh n = random_mesh(4, 2, 1);
    n.vertices[1].y = std::numeric_limits<float>::quiet_NaN();
    CHECK_THROWS_AS((void)to_ply(n), std::invalid_argument);
    CHECK_THROWS_AS(write_ply("/nonexistent-dir/x.ply", random_mesh(3, 1, 1)), LoadError);
}

namespace {
/// A file with extra properties of every type, list counts of several integer types, a
/// mixed-type x/y/z, an unknown element with lists before `vertex` and one after `face`.
std::string every_type_file(PlyEncoding enc) {
    const bool ascii = enc == PlyEncoding::ascii;
    std::string h = "ply\nformat ";
    h += ascii ? "ascii" : enc == PlyEncoding::binary_little_endian ? "binary_little_endian" : "binary_big_endian";
    h += " 1.0\ncomment every type\nobj_info made by a test\n"
         "element edge 2\nproperty int vertex1\nproperty list ushort char tags\n"
         "element vertex 4\n"
         "property char a\nproperty uchar b\nproperty short c\nproperty ushort d\nproperty float x\n"
         "property int e\nproperty uint f\nproperty double y\nproperty float32 g\nproperty int16 z\n"
         "property double h\nproperty list uint8 float normal\nproperty uint8 red\n"
         "element face 3\n"
         "property uchar flags\nproperty list uint uint vertex_indices\nproperty list char double extra\nproperty float quality\n"
         "element material 1\nproperty list int uchar name\nproperty float shine\n"
         "end_header\n";
    const float xs[4] = {0.5f, -1.25f, 3.0f, 1e-3f};
    const double ys[4] = {2.0, -0.75, 1e10, 0.1};
    const short zs[4] = {7, -3, 0, 32767};
    if (ascii) {
        h += "10 2 1 2\n-5 0\n";
        for (int i = 0; i < 4; ++i) {
            std::ostringstream s;
            s.precision(17);
            s << "-7 200 -300 60000 " << xs[i] << " -100000 4000000000 " << ys[i] << " 1.5 " << zs[i] << " 2.5e-300 3 0.1 0.2 0.3 255\n";
            h += s.str();
        }
        h += "1 3 0 1 2 2 1.5 2.5 0.25\n0 4 1 2 3 0 0 0.5\n255 3 3 2 1 1 -1e300 7\n";
        h += "3 65 66 67 0.5\n";
        return h;
    }
    Bytes b;
    b.big = enc == PlyEncoding::binary_big_endian;
    b.text(h);
    b.put<std::int32_t>(10).put<std::uint16_t>(2).put<std::int8_t>(1).put<std::int8_t>(2);
    b.put<std::int32_t>(-5).put<std::uint16_t>(0);
    for (int i = 0; i < 4; ++i) {
        b.put<std::int8_t>(-7).put<std::uint8_t>(200).put<std::int16_t>(-300).put<std::uint16_t>(60000).put<float>(xs[i]);
        b.put<std::int32_t>(-100000).put<std::uint32_t>(4000000000u).put<double>(ys[i]).put<float>(1.5f).put<std::int16_t>(zs[i]);
        b.put<double>(2.5e-300).put<std::uint8_t>(3).put<float>(0.1f).put<float>(0.2f).put<float>(0.3f).put<std::uint8_t>(255);
    }
    b.put<std::uint8_t>(1).put<std::uint32_t>(3).put<std::uint32_t>(0).put<std::uint32_t>(1).put<std::uint32_t>(2);
    b.put<std::int8_t>(2).put<double>(1.5).put<double>(2.5).put<float>(0.25f);
    b.put<std::uint8_t>(0).put<std::uint32_t>(4).put<std::uint32_t>(1).put<std::uint32_t>(2).put<std::uint32_t>(3).put<std::uint32_t>(0);
    b.put<std::int8_t>(0).put<float>(0.5f);
    b.put<std::uint8_t>(255).put<std::uint32_t>(3).put<std::uint32_t>(3).put<std::uint32_t>(2).put<std::uint32_t>(1);
    b.put<std::int8_t>(1).put<double>(-1e300).put<float>(7.0f);
    b.put<std::int32_t>(3).put<std::uint8_t>(65).put<std::uint8_t>(66).put<std::uint8_t>(67).put<float>(0.5f);
    return b.s;
}
} // namespace

TEST_CASE("extra properties of every type are skipped, in every encoding") {
    const float xs[4] = {0.5f, -1.25f, 3.0f, 1e-3f};
    const double ys[4] = {2.0, -0.75, 1e10, 0.1};
    const short zs[4] = {7, -3, 0, 32767};
    for (PlyEncoding enc : encodings) {
        CAPTURE(static_cast<int>(enc));
        const Mesh m = parse(every_type_file(enc));
        REQUIRE(m.vertices.size() == 4);
        for (int i = 0; i < 4; ++i) {
            CHECK(m.vertices[static_cast<std::size_t>(i)].x == xs[i]);
            CHECK(m.vertices[static_cast<std::size_t>(i)].y == static_cast<float>(ys[i]));
            CHECK(m.vertices[static_cast<std::size_t>(i)].z == static_cast<float>(zs[i]));
        }
        const std::vector<std::array<std::uint32_t, 3>> faces = {{0, 1, 2}, {1, 2, 3}, {1, 3, 0}, {3, 2, 1}};
        CHECK(m.faces == faces);
    }
}

TEST_CASE("fixed-size vertices with mixed coordinate types and extra values") {
    for (bool big : {false, true}) {
        Bytes b;
        b.big = big;
        b.text(std::string("ply\nformat ") + (big ? "binary_big_endian" : "binary_little_endian") +
               " 1.0\nelement vertex 2\nproperty uchar r\nproperty double x\nproperty ushort q\nproperty float y\n"
               "property int z\nproperty char s\nend_header\n");
        b.put<std::uint8_t>(9).put<double>(0.1).put<std::uint16_t>(7).put<float>(-2.5f).put<std::int32_t>(-40000).put<std::int8_t>(-1);
        b.put<std::uint8_t>(8).put<double>(1e20).put<std::uint16_t>(6).put<float>(3e-30f).put<std::int32_t>(123).put<std::int8_t>(5);
        const Mesh m = parse(b.s);
        REQUIRE(m.vertices.size() == 2);
        CHECK(m.vertices[0] == Vec3f{0.1f, -2.5f, -40000.0f});
        CHECK(m.vertices[1] == Vec3f{1e20f, 3e-30f, 123.0f});
    }
}

TEST_CASE("polygons are fan-triangulated; faces with fewer than 3 indices are skipped") {
    const std::string header = "element vertex 6\nproperty float x\nproperty float y\nproperty float z\n"
                               "element face 5\nproperty list uchar int vertex_indices\nend_header\n";
    const std::vector<std::array<std::uint32_t, 3>> expected = {{0, 1, 2}, {0, 2, 3},            // quad
                                                                {5, 4, 3}, {5, 3, 2}, {5, 2, 1}, // pentagon
                                                                {1, 2, 3}};                      // triangle
    std::string ascii = "ply\nformat ascii 1.0\n" + header;
    for (int i = 0; i < 6; ++i) ascii += std::to_string(i) + " 0 0\n";
    ascii += "4 0 1 2 3\n5 5 4 3 2 1\n2 0 1\n0\n3 1 2 3\n";
    CHECK(parse(ascii).faces == expected);
    for (bool big : {false, true}) {
        Bytes b;
        b.big = big;
        b.text(std::string("ply\nformat ") + (big ? "binary_big_endian" : "binary_little_endian") + " 1.0\n" + header);
        for (int i = 0; i < 6; ++i) b.put<float>(float(i)).put<float>(0).put<float>(0);
        // a triangle first, so the fast path runs and hands over to the generic loop at the quad
        b.put<std::uint8_t>(3).put<std::int32_t>(1).put<std::int32_t>(2).put<std::int32_t>(3);
        b.put<std::uint8_t>(4).put<std::int32_t>(0).put<std::int32_t>(1).put<std::int32_t>(2).put<std::int32_t>(3);
        b.put<std::uint8_t>(5);
        for (int v : {5, 4, 3, 2, 1}) b.put<std::int32_t>(v);
        b.put<std::uint8_t>(2).put<std::int32_t>(0).put<std::int32_t>(1);
        b.put<std::uint8_t>(0);
        const std::vector<std::array<std::uint32_t, 3>> expected_b = {{1, 2, 3}, {0, 1, 2}, {0, 2, 3}, {5, 4, 3}, {5, 3, 2}, {5, 2, 1}};
        CHECK(parse(b.s).faces == expected_b);
    }
}

TEST_CASE("other PLY details: CRLF header, no face element, zero-property elements, trailing data") {
    const Mesh a = parse("ply\r\nformat ascii 1.0\r\nelement vertex 2\r\nproperty float x\r\nproperty float y\r\nproperty float z\r\n"
                         "element nothing 1000000000000\r\nend_header\r\n1 2 3\r\n\r\n4 5 6\r\ntrailing words are ignored\n");
    REQUIRE(a.vertices.size() == 2);
    CHECK(a.vertices[1] == Vec3f{4, 5, 6});
    CHECK(a.faces.empty());
    Bytes b;
    b.text("ply\nformat binary_little_endian 1.0\nelement nothing 1000000000000\nelement vertex 1\nproperty float x\nproperty float y\n"
           "property float z\nend_header\n");
    b.put<float>(1).put<float>(2).put<float>(3).put<float>(99);
    const Mesh c = parse(b.s);
    REQUIRE(c.vertices.size() == 1);
    CHECK(c.vertices[0] == Vec3f{1, 2, 3});
}

TEST_CASE("malformed PLY: every case is a LoadError naming the file and the line or byte") {
    const std::string vhead = "element vertex 3\nproperty float x\nproperty float y\nproperty float z\n";
    const std::string fhead = "element face 1\nproperty list uchar int vertex_indices\nend_header\n";
    const std::string ascii = "ply\nformat ascii 1.0\n" + vhead + fhead;
    const std::string le = "ply\nformat binary_little_endian 1.0\n" + vhead + fhead;
    auto le_file = [&](float x0, std::int32_t i2) {
        Bytes b;
        b.text(le);
        b.put<float>(x0).put<float>(0).put<float>(0).put<float>(1).put<float>(0).put<float>(0).put<float>(0).put<float>(1).put<float>(0);
        b.put<std::uint8_t>(3).put<std::int32_t>(0).put<std::int32_t>(1).put<std::int32_t>(i2);
        return b.s;
    };
    REQUIRE(parse(le_file(0, 2)).faces.size() == 1);

    SUBCASE("not PLY, unknown format, keywords, types") {
        CHECK(mentions(parse_error(""), "empty"));
        CHECK(parse_error("plx\nformat ascii 1.0\n").where() == "line 1");
        CHECK(parse_error("ply\nformat binary_middle_endian 1.0\n" + vhead + fhead).where() == "line 2");
        CHECK(parse_error("ply\nformat ascii 2.0\n" + vhead + fhead).where() == "line 2");
        const LoadError k = parse_error("ply\nformat ascii 1.0\nelephant vertex 3\n" + vhead + fhead);
        CHECK(k.where() == "line 3");
        CHECK(mentions(k, "elephant"));
        CHECK(parse_error("ply\nformat ascii 1.0\nelement vertex 3\nproperty flaot x\n").where() == "line 4");
        CHECK(parse_error("ply\nformat ascii 1.0\nelement vertex -3\n").where() == "line 3");
        CHECK(parse_error("ply\nformat ascii 1.0\nelement vertex 3x\n").where() == "line 3");
        CHECK(parse_error("ply\nformat ascii 1.0\nproperty float x\n").where() == "line 3");
        CHECK(parse_error("ply\nformat ascii 1.0\nelement vertex 1\nproperty list float int x\n").where() == "line 4");
        CHECK(parse_error("ply\nformat ascii 1.0\n" + vhead + "element face 1\nproperty list uchar float vertex_indices\n").where() == "line 8");
        CHECK(mentions(parse_error("ply\nformat ascii 1.0\n" + vhead), "end_header"));
        CHECK(mentions(parse_error("ply\n" + vhead + fhead + "0 0 0\n"), "format"));
    }
    SUBCASE("missing vertex element, x/y/z, index list") {
        CHECK(mentions(parse_error("ply\nformat ascii 1.0\n" + fhead), "vertex"));
        const LoadError y = parse_error("ply\nformat ascii 1.0\nelement vertex 1\nproperty float x\nproperty float z\nend_header\n1 2\n");
        CHECK(y.where() == "line 3");
        CHECK(mentions(y, "'y'"));
        CHECK(mentions(parse_error("ply\nformat ascii 1.0\n" + vhead + "element face 1\nproperty list uchar int idx\nend_header\n"),
                       "vertex_indices"));
        CHECK(mentions(parse_error("ply\nformat ascii 1.0\nelement vertex 1\nproperty float x\nproperty float x\n"), "duplicate"));
    }
    SUBCASE("truncated data: every prefix of a binary file fails, never reads past the end") {
        for (PlyEncoding enc : {PlyEncoding::binary_little_endian, PlyEncoding::binary_big_endian}) {
            const std::string full = every_type_file(enc);
            const std::size_t data = full.find("end_header\n") + 11;
            for (std::size_t n = 0; n < full.size(); ++n) {
                // an exact-size copy, so ASan sees any read past the end
                const std::unique_ptr<char[]> copy(new char[n == 0 ? 1 : n]);
                std::memcpy(copy.get(), full.data(), n);
                try {
                    (void)read_ply(std::span<const char>(copy.get(), n), "cut.ply");
                    FAIL("prefix " << n << " of " << full.size() << " parsed");
                } catch (const LoadError& e) {
                    // "end_header" without its newline also ends the header
                    const char* expected = n + 1 >= data ? "byte " : "line ";
                    CHECK_MESSAGE(e.where().rfind(expected, 0) == 0, std::string(e.what()));
                }
            }
        }
        // ascii: every prefix that lacks at least the last value fails with a line number
        const std::string full = every_type_file(PlyEncoding::ascii);
        const std::size_t last_token = full.find_last_of(' ') + 1;
        for (std::size_t n = 0; n < last_token; ++n) {
            try {
                (void)parse(full.substr(0, n), "cut.ply");
                FAIL("ascii prefix " << n << " parsed");
            } catch (const LoadError& e) {
                CHECK_MESSAGE(e.where().rfind("line ", 0) == 0, std::string(e.what()));
            }
        }
        CHECK(parse_error(ascii + "0 0 0\n1 0 0\n").where() == "line 12");
    }
    SUBCASE("counts larger than the data are caught before allocating") {
        const std::string huge = "ply\nformat binary_little_endian 1.0\nelement vertex 4000000000\nproperty float x\nproperty float y\n"
                                 "property float z\nend_header\n";
        const LoadError v = parse_error(huge + std::string(24, '\0'));
        CHECK(v.where() == "byte " + std::to_string(huge.size()));
        CHECK(mentions(v, "truncated"));
        CHECK(mentions(parse_error("ply\nformat binary_big_endian 1.0\nelement vertex 99999999999\nproperty float x\nproperty float y\n"
                                   "property float z\nend_header\n"),
                       "32-bit"));
        Bytes f;
        f.text("ply\nformat binary_little_endian 1.0\n" + vhead + "element face 18446744073709551615\n"
               "property list uchar int vertex_indices\nend_header\n");
        for (int i = 0; i < 9; ++i) f.put<float>(0);
        f.put<std::uint8_t>(3).put<std::int32_t>(0).put<std::int32_t>(1).put<std::int32_t>(2);
        CHECK(mentions(parse_error(f.s), "unexpected end"));
        // lists whose counts lie
        Bytes l;
        l.text("ply\nformat binary_little_endian 1.0\n" + vhead + "element face 1\nproperty list uint int vertex_indices\nend_header\n");
        for (int i = 0; i < 9; ++i) l.put<float>(0);
        l.put<std::uint32_t>(4000000000u).put<std::int32_t>(0);
        CHECK(parse_error(l.s).where().rfind("byte ", 0) == 0);
        Bytes n;
        n.text("ply\nformat binary_little_endian 1.0\n" + vhead + "element face 1\nproperty list char int vertex_indices\nend_header\n");
        for (int i = 0; i < 9; ++i) n.put<float>(0);
        n.put<std::int8_t>(-1);
        CHECK(mentions(parse_error(n.s), "negative"));
        CHECK(mentions(parse_error("ply\nformat ascii 1.0\nelement vertex 4000000000\nproperty float x\nproperty float y\n"
                                   "property float z\nend_header\n1 2 3\n"),
                       "unexpected end"));
    }
    SUBCASE("indices out of range") {
        const std::string bad = le_file(0, 3);
        const LoadError e = parse_error(bad);
        CHECK(e.where() == "byte " + std::to_string(bad.size() - 4));  // the offending index itself
        CHECK(mentions(e, "vertex 3"));
        CHECK(parse_error(le_file(0, -1)).where() == "byte " + std::to_string(bad.size() - 4));
        Bytes big;  // the generic path (ushort count) and big-endian
        big.big = true;
        big.text("ply\nformat binary_big_endian 1.0\n" + vhead + "element face 1\nproperty list ushort uint vertex_indices\nend_header\n");
        for (int i = 0; i < 9; ++i) big.put<float>(0);
        big.put<std::uint16_t>(3).put<std::uint32_t>(0).put<std::uint32_t>(7).put<std::uint32_t>(1);
        CHECK(parse_error(big.s).where() == "byte " + std::to_string(big.s.size() - 8));
        CHECK(parse_error(ascii + "0 0 0\n1 0 0\n0 1 0\n3 0 1 3\n").where() == "line 13");
        CHECK(parse_error(ascii + "0 0 0\n1 0 0\n0 1 0\n3 0 -1 2\n").where() == "line 13");
        CHECK(parse_error(ascii + "0 0 0\n1 0 0\n0 1 0\n2 0 9\n").where() == "line 13");  // checked even when skipped
    }
    SUBCASE("NaN and infinite coordinates") {
        const std::string nan = le_file(std::numeric_limits<float>::quiet_NaN(), 2);
        CHECK(parse_error(nan).where() == "byte " + std::to_string(le.size()));
        CHECK(mentions(parse_error(le_file(-std::numeric_limits<float>::infinity(), 2)), "non-finite"));
        Bytes d;  // a finite double that overflows float
        d.text("ply\nformat binary_little_endian 1.0\nelement vertex 2\nproperty double x\nproperty double y\nproperty double z\nend_header\n");
        d.put<double>(0).put<double>(0).put<double>(0).put<double>(0).put<double>(1e300).put<double>(0);
        CHECK(parse_error(d.s).where() == "byte " + std::to_string(d.s.size() - 24));
        CHECK(parse_error(ascii + "0 0 0\nnan 0 0\n").where() == "line 11");
        CHECK(parse_error(ascii + "0 0 0\n1 inf 0\n").where() == "line 11");
        CHECK(parse_error(ascii + "0 0 0\n1 0 1e999\n").where() == "line 11");
    }
    SUBCASE("bad ascii values") {
        CHECK(mentions(parse_error(ascii + "0 0 0\n1 0x 0\n"), "'0x'"));
        CHECK(mentions(parse_error(ascii + "0 0 0\n1 0\n"), "missing value"));
        CHECK(mentions(parse_error(ascii + "0 0 0\n1 0 0 5\n"), "extra value"));
        CHECK(parse_error(ascii + "0 0 0\n1 0 0\n0 1 0\n3 0 1 2.5\n").where() == "line 13");
        CHECK(parse_error(ascii + "0 0 0\n1 0 0\n0 1 0\n-3 0 1 2\n").where() == "line 13");
    }
}

TEST_CASE("read_ply from a path: missing file and directory are LoadErrors") {
    CHECK_THROWS_AS((void)read_ply(std::string("/nonexistent/x.ply")), LoadError);
    try {
        (void)read_ply(std::filesystem::temp_directory_path().string());
        FAIL("a directory was read");
    } catch (const LoadError& e) {
        CHECK(mentions(e, "directory"));
    }
}

// ---- issue 16.6 and 16.8: a byte-order mark, and a binary body longer than its header --------

TEST_CASE("PLY with a UTF-8 byte-order mark reads as without it, in every encoding") {
    const Mesh m = random_mesh(50, 80, 11);
    for (const auto enc : {PlyEncoding::ascii, PlyEncoding::binary_little_endian, PlyEncoding::binary_big_endian}) {
        const std::string plain = to_ply(m, enc);
        const Mesh a = parse("\xEF\xBB\xBF" + plain);
        CHECK(a.vertices == m.vertices);
        CHECK(a.faces == m.faces);
    }
    // Errors keep their line numbers.
    try {
        (void)parse("\xEF\xBB\xBFply\nformat ascii 1.0\nbogus\nend_header\n");
        FAIL("no error");
    } catch (const LoadError& e) {
        CHECK(e.where() == "line 3");
    }
}

TEST_CASE("binary PLY whose body is longer than its header implies: a warning, or an error without faces") {
    const Mesh m = random_mesh(40, 60, 12);
    for (const auto enc : {PlyEncoding::binary_little_endian, PlyEncoding::binary_big_endian}) {
        const std::string good = to_ply(m, enc);
        // Any number of extra bytes: the mesh loads, the caller is told where the surplus starts.
        for (const std::size_t extra : {std::size_t(1), std::size_t(3), std::size_t(8), std::size_t(1000)}) {
            CAPTURE(extra);
            const std::string bytes = good + std::string(extra, '\x7f');
            std::string warnings;
            const Mesh a = read_ply(std::span<const char>(bytes.data(), bytes.size()), "long.ply", &warnings);
            CHECK(a.faces == m.faces);
            CHECK(warnings.find("long.ply: byte " + std::to_string(good.size()) + ": " + std::to_string(extra) + " bytes after the last element") == 0);
            CHECK_NOTHROW((void)parse(bytes));   // without a warnings string: still loads
        }
        std::string warnings;   // a final line break alone is not worth a warning
        (void)read_ply(std::span<const char>((good + "\n").data(), good.size() + 1), "nl.ply", &warnings);
        CHECK(warnings.empty());
        (void)read_ply(std::span<const char>(good.data(), good.size()), "exact.ply", &warnings);
        CHECK(warnings.empty());
    }
    // Doubles written under 'property float': never a silent load.
    for (const bool big : {false, true}) {
        Bytes b;
        b.big = big;
        b.text(std::string("ply\nformat ") + (big ? "binary_big_endian" : "binary_little_endian") +
               " 1.0\nelement vertex 4\nproperty float x\nproperty float y\nproperty float z\n"
               "element face 2\nproperty list uchar int vertex_indices\nend_header\n");
        for (const double v : {0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 1.0, 0.0, 1.0, 1.0, 0.0}) b.put<double>(v);
        b.put<std::uint8_t>(3).put<std::int32_t>(0).put<std::int32_t>(1).put<std::int32_t>(2);
        b.put<std::uint8_t>(3).put<std::int32_t>(1).put<std::int32_t>(3).put<std::int32_t>(2);
        std::string warnings;
        try {
            const Mesh a = read_ply(std::span<const char>(b.s.data(), b.s.size()), "doubles.ply", &warnings);
            CHECK(!a.faces.empty());            // loaded faces: then the caller was warned
            CHECK(!warnings.empty());
        } catch (const LoadError& e) {
            CHECK(e.file() == "doubles.ply");
        }
    }
    // No face survives (all have fewer than 3 indices) and bytes are left: an error at the surplus.
    Bytes c;
    c.text("ply\nformat binary_little_endian 1.0\nelement vertex 3\nproperty float x\nproperty float y\nproperty float z\n"
           "element face 2\nproperty list uchar int vertex_indices\nend_header\n");
    for (int i = 0; i < 9; ++i) c.put<float>(float(i));
    c.put<std::uint8_t>(2).put<std::int32_t>(0).put<std::int32_t>(1);
    c.put<std::uint8_t>(1).put<std::int32_t>(2);
    const std::size_t end = c.s.size();
    CHECK(parse(c.s).faces.empty());            // exact length: a mesh of no triangles, as before
    c.put<std::int32_t>(7);
    try {
        (void)parse(c.s, "nofaces.ply");
        FAIL("no error");
    } catch (const LoadError& e) {
        CHECK(e.file() == "nofaces.ply");
        CHECK(e.where() == "byte " + std::to_string(end));
        CHECK(mentions(e, "no face was read"));
    }
}
