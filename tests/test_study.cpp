// The study executable on a tiny scene, end to end: the JSON has every scene x builder x resolution,
// FPS is frames / (build + trace) of its own per-frame data, the SAH of a hand-computed 2-triangle
// tree is exact, the renders are not empty, and bad input fails with a message naming it.
#include <doctest/doctest.h>

#include <cmath>
#include <cstdlib>
#include <sys/wait.h>
#include <filesystem>
#include <fstream>
#include <map>
#include <memory>
#include <sstream>
#include <set>
#include <string>
#include <variant>
#include <vector>

#if defined(DYNBVH_STUDY_EXE)

namespace {

// ---- a minimal JSON reader (enough for study.json) ----
struct Json;
using JsonObject = std::map<std::string, Json>;
using JsonArray = std::vector<Json>;
struct Json {
    std::variant<std::nullptr_t, bool, double, std::string, std::shared_ptr<JsonArray>, std::shared_ptr<JsonObject>> v;
    bool is_null() const { return std::holds_alternative<std::nullptr_t>(v); }
    double num() const { return std::get<double>(v); }
    const std::string& str() const { return std::get<std::string>(v); }
    const JsonArray& arr() const { return *std::get<std::shared_ptr<JsonArray>>(v); }
    const JsonObject& obj() const { return *std::get<std::shared_ptr<JsonObject>>(v); }
    const Json& operator[](const std::string& k) const {
        const auto& o = obj();
        const auto it = o.find(k);
        if (it == o.end()) throw std::runtime_error("JSON: no key " + k);
        return it->second;
    }
};

class JsonParser {
public:
    explicit JsonParser(const std::string& s) : s_(s) {}
    Json parse() {
        Json j = value();
        ws();
        if (i_ != s_.size()) fail("trailing characters");
        return j;
    }

private:
    [[noreturn]] void fail(const std::string& why) { throw std::runtime_error("JSON: " + why + " at byte " + std::to_string(i_)); }
    void ws() {
        while (i_ < s_.size() && (s_[i_] == ' ' || s_[i_] == '\n' || s_[i_] == '\t' || s_[i_] == '\r')) ++i_;
    }
    bool eat(char c) {
        ws();
        if (i_ < s_.size() && s_[i_] == c) {
            ++i_;
            return true;
        }
        return false;
    }
    Json value() {
        ws();
        if (i_ >= s_.size()) fail("unexpected end");
        const char c = s_[i_];
        if (c == '{') {
            ++i_;
            auto o = std::make_shared<JsonObject>();
            if (!eat('}')) {
                do {
                    ws();
                    const std::string k = string();
                    if (!eat(':')) fail("expected :");
                    (*o)[k] = value();
                } while (eat(','));
                if (!eat('}')) fail("expected }");
            }
            return Json{o};
        }
        if (c == '[') {
            ++i_;
            auto a = std::make_shared<JsonArray>();
            if (!eat(']')) {
                do a->push_back(value());
                while (eat(','));
                if (!eat(']')) fail("expected ]");
            }
            return Json{a};
        }
        if (c == '"') return Json{string()};
        if (s_.compare(i_, 4, "null") == 0) { i_ += 4; return Json{nullptr}; }
        if (s_.compare(i_, 4, "true") == 0) { i_ += 4; return Json{true}; }
        if (s_.compare(i_, 5, "false") == 0) { i_ += 5; return Json{false}; }
        std::size_t used = 0;
        const double d = std::stod(s_.substr(i_, 64), &used);
        if (used == 0) fail("bad number");
        i_ += used;
        return Json{d};
    }
    std::string string() {
        if (i_ >= s_.size() || s_[i_] != '"') fail("expected string");
        ++i_;
        std::string o;
        while (i_ < s_.size() && s_[i_] != '"') {
            if (s_[i_] == '\\') {
                ++i_;
                const char e = s_[i_];
                if (e == 'n') o += '\n';
                else if (e == 't') o += '\t';
                else if (e == 'r') o += '\r';
                else if (e == 'u') { o += '?'; i_ += 4; }
                else o += e;
                ++i_;
            } else {
                o += s_[i_++];
            }
        }
        if (i_ >= s_.size()) fail("unterminated string");
        ++i_;
        return o;
    }
    const std::string& s_;
    std::size_t i_ = 0;
};

std::string read_all(const std::filesystem::path& p) {
    std::ifstream in(p, std::ios::binary);
    std::stringstream ss;
    ss << in.rdbuf();
    return ss.str();
}

/// Runs dynbvh-study with `args`; stdout and stderr go to `log`. Returns the exit status.
int run_study(const std::string& args, const std::filesystem::path& log) {
    const std::string cmd = std::string("\"") + DYNBVH_STUDY_EXE + "\" " + args + " > \"" + log.string() + "\" 2>&1";
    const int rc = std::system(cmd.c_str());
    return WIFEXITED(rc) ? WEXITSTATUS(rc) : -1;
}

const std::filesystem::path tmp = DYNBVH_STUDY_TMP;

} // namespace

TEST_CASE("study: tiny cloth-ball run has every group, consistent FPS and non-empty renders") {
    const auto out = tmp / "tiny";
    std::filesystem::remove_all(out);
    std::filesystem::create_directories(out);
    const int rc = run_study("--scenes cloth-ball --scale 0.02 --frames 2 --builders lbvh,ploc --res 64x48,32x24 --images 2 "
                             "--threads 2 --out \"" + out.string() + "\"",
                             out / "log.txt");
    INFO(read_all(out / "log.txt"));
    REQUIRE(rc == 0);
    const std::string text = read_all(out / "study.json");
    const Json j = JsonParser(text).parse();

    CHECK(j["threads"].num() >= 1);
    CHECK(!j["machine"]["cpu"].str().empty());
    CHECK(!j["compiler"].str().empty());
    CHECK(!j["date"].str().empty());

    const auto& results = j["results"].arr();
    REQUIRE(results.size() == 4);   // 1 scene x 2 builders x 2 resolutions
    for (const char* b : {"lbvh", "ploc"})
        for (int w : {64, 32}) {
            int found = 0;
            for (const auto& g : results)
                if (g["scene"].str() == "cloth-ball" && g["builder"].str() == b && g["width"].num() == w) ++found;
            CHECK_MESSAGE(found == 1, b << " at width " << w);
        }
    std::size_t records = 0;
    for (const auto& g : results) {
        const auto& frames = g["per_frame"].arr();
        REQUIRE(frames.size() == 2);
        records += frames.size();
        double build = 0, trace = 0, sah = 0;
        for (const auto& f : frames) {
            CHECK(f["build_ms"].num() >= 0);
            CHECK(f["trace_ms"].num() > 0);
            CHECK(f["triangles"].num() > 100);
            CHECK(f["hits"].num() > 0);
            CHECK(f["hits"].num() < g["rays_per_frame"].num());
            build += f["build_ms"].num();
            trace += f["trace_ms"].num();
            sah += f["sah"].num();
        }
        CHECK(g["rays_per_frame"].num() == g["width"].num() * g["height"].num());
        CHECK(g["fps"].num() == doctest::Approx(2.0 / ((build + trace) / 1000.0)).epsilon(1e-12));
        CHECK(g["mean_build_ms"].num() == doctest::Approx(build / 2).epsilon(1e-12));
        CHECK(g["mean_trace_ms"].num() == doctest::Approx(trace / 2).epsilon(1e-12));
        CHECK(g["mean_sah"].num() == doctest::Approx(sah / 2).epsilon(1e-12));
        CHECK(g["mean_memory_bytes"].num() > 0);
    }
    // Both builders hit the same number of pixels (exact closest hits through different trees).
    for (const auto& a : results)
        for (const auto& b : results)
            if (a["width"].num() == b["width"].num())
                for (std::size_t k = 0; k < 2; ++k)
                    CHECK(a["per_frame"].arr()[k]["hits"].num() == b["per_frame"].arr()[k]["hits"].num());

    const auto& images = j["images"].arr();
    REQUIRE(images.size() == 2);
    for (const auto& im : images) {
        CHECK(im["hit_pixels"].num() > 0);
        CHECK(im["hit_pixels"].num() < im["width"].num() * im["height"].num());
        const std::string png = read_all(out / im["file"].str());
        REQUIRE(png.size() > 8);
        CHECK(png.compare(0, 8, "\x89PNG\r\n\x1a\n") == 0);
    }
    // CSV: a header and one row per frame record.
    const std::string csv = read_all(out / "study.csv");
    std::size_t lines = 0;
    for (char c : csv) lines += c == '\n';
    CHECK(lines == records + 1);
    const std::string report = read_all(out / "report.md");
    CHECK(report.find("Table 5.2") != std::string::npos);
    CHECK(report.find("fig_build_vs_triangles.svg") != std::string::npos);
    CHECK(std::filesystem::file_size(out / "fig_build_vs_triangles.svg") > 200);
}

TEST_CASE("study: SAH of a 2-triangle scene is exact, and --info describes it") {
    const auto out = tmp / "two";
    std::filesystem::remove_all(out);
    std::filesystem::create_directories(out);
    // Two unit right triangles 100 apart in z = 0: boxes of area 2 each, root box [0,101]x[0,1]x{0} of area 202.
    // Two leaves under one root beat one leaf of two (3 * 202 + 2 * (2 + 2) < 2 * 2 * 202), so
    // SAH = (Ct * 202 + Ci * (2 * 1 + 2 * 1)) / 202 = (3 * 202 + 8) / 202.
    {
        std::ofstream ply(out / "two.ply");
        ply << "ply\nformat ascii 1.0\nelement vertex 6\nproperty float x\nproperty float y\nproperty float z\n"
               "element face 2\nproperty list uchar int vertex_indices\nend_header\n"
               "0 0 0\n1 0 0\n0 1 0\n100 0 0\n101 0 0\n100 1 0\n3 0 1 2\n3 3 4 5\n";
    }
    const double expected = (3.0 * 202.0 + 8.0) / 202.0;
    const int rc = run_study("--scenes \"" + (out / "two.ply").string() + "\" --builders lbvh,ploc:wide=4,kbvh:wide=8,binned-sah,lbvh:wide=0 --res 16x16 "
                             "--images 0 --out \"" + out.string() + "\"",
                             out / "log.txt");
    INFO(read_all(out / "log.txt"));
    REQUIRE(rc == 0);
    const Json j = JsonParser(read_all(out / "study.json")).parse();
    const auto& results = j["results"].arr();
    REQUIRE(results.size() == 5);
    std::set<double> default_bytes;
    for (const auto& g : results) {
        INFO(g["builder"].str());
        CHECK(g["per_frame"].arr()[0]["sah"].num() == doctest::Approx(expected).epsilon(1e-12));
        CHECK(g["per_frame"].arr()[0]["triangles"].num() == 2);
        // the traced tree: 3 binary nodes (32 bytes each), one 4-wide node (128 bytes) or one 8-wide node
        // (256 bytes), plus 2 references; lbvh and binned-sah trace the default width (4, or 8 with AVX)
        const std::string name = g["builder"].str();
        const double bytes = g["per_frame"].arr()[0]["memory_bytes"].num() - 2 * 4;
        if (name.find("wide=0") != std::string::npos) CHECK(bytes == 3 * 32);
        else if (name.starts_with("ploc")) CHECK(bytes == 128);
        else if (name.starts_with("kbvh")) CHECK(bytes == 256);
        else default_bytes.insert(bytes);
    }
    CHECK(default_bytes.size() == 1);
    CHECK((default_bytes.count(128) + default_bytes.count(256)) == 1);

    const int rc2 = run_study("--info \"" + (out / "two.ply").string() + "\"", out / "info.json");
    REQUIRE(rc2 == 0);
    const Json info = JsonParser(read_all(out / "info.json")).parse();
    CHECK(info["triangles"].num() == 2);
    CHECK(info["frames"].num() == 1);
    CHECK(info["format"].str() == "ply");
    CHECK(info["bounds"]["min"].arr()[0].num() == 0);
    CHECK(info["bounds"]["max"].arr()[0].num() == 101);
    CHECK(info["bounds"]["max"].arr()[1].num() == 1);
    CHECK(info["topology_changes"].v == Json{false}.v);
}

TEST_CASE("study: bad input fails with a message naming it") {
    const auto out = tmp / "bad";
    std::filesystem::create_directories(out);
    CHECK(run_study("--scenes no-such-scene-xyz --out \"" + out.string() + "\"", out / "log1.txt") != 0);
    CHECK(read_all(out / "log1.txt").find("no-such-scene-xyz") != std::string::npos);
    CHECK(run_study("--builders lbvh,octree --out \"" + out.string() + "\"", out / "log2.txt") != 0);
    CHECK(read_all(out / "log2.txt").find("octree") != std::string::npos);
    CHECK(run_study("--res 640by480", out / "log3.txt") == 2);
    CHECK(read_all(out / "log3.txt").find("640by480") != std::string::npos);
    {
        std::ofstream bad(out / "broken.ply");
        bad << "ply\nformat ascii 1.0\nelement vertex 3\nproperty float x\nend_header\n1\n";
    }
    CHECK(run_study("--info \"" + (out / "broken.ply").string() + "\"", out / "log4.txt") != 0);
    CHECK(read_all(out / "log4.txt").find("broken.ply") != std::string::npos);
}

#else

TEST_CASE("study: skipped") {
    MESSAGE("dynbvh-study is not part of this build (DYNBVH_BUILD_BENCH=OFF): study test skipped");
}

#endif
