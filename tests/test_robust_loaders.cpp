// The loaders against the fuzzers' inputs (issue 5): every seed of fuzz/corpus/ is a valid file that
// loads, and every input a fuzzer found crashing (see fuzz/run.sh) is replayed here as a regression
// test: it must load or throw io::LoadError naming the file, nothing else.
#include <doctest/doctest.h>

#include <dynbvh/io/bart.hpp>
#include <dynbvh/io/obj.hpp>
#include <dynbvh/io/ply.hpp>

#include <filesystem>
#include <fstream>
#include <functional>
#include <iterator>
#include <optional>
#include <span>
#include <sstream>
#include <string>
#include <vector>

using namespace dynbvh;

namespace {

const std::filesystem::path corpus_dir = std::filesystem::path(__FILE__).parent_path().parent_path() / "fuzz" / "corpus";

std::string slurp(const std::filesystem::path& p) {
    std::ifstream in(p, std::ios::binary);
    return {std::istreambuf_iterator<char>(in), std::istreambuf_iterator<char>()};
}

std::vector<std::filesystem::path> files_in(const std::string& format) {
    std::vector<std::filesystem::path> out;
    const auto dir = corpus_dir / format;
    if (!std::filesystem::is_directory(dir)) return out;
    for (const auto& e : std::filesystem::directory_iterator(dir))
        if (e.is_regular_file()) out.push_back(e.path());
    std::sort(out.begin(), out.end());
    return out;
}

// The fuzz targets' own calls (fuzz/fuzz_*.cpp), so a corpus file or a crash input is replayed exactly.
io::Mesh load_ply(const std::string& bytes) { return io::read_ply(std::span<const char>(bytes.data(), bytes.size()), "fuzz.ply"); }

io::Mesh load_obj(const std::string& bytes) {
    std::string warnings;
    return io::read_obj(std::span<const char>(bytes.data(), bytes.size()), "fuzz.obj", "", &warnings);
}

std::size_t load_bart(const std::string& input) {
    const std::size_t cut = input.find("\n#@@\n");
    const std::string text = input.substr(0, cut);
    const std::string included = cut == std::string::npos ? std::string("p 3 0 0 0 1 0 0 0 1 0\n") : input.substr(cut + 5);
    io::BartOptions opt;
    opt.max_include_depth = 3;
    opt.max_includes = 16;
    opt.max_bytes = std::uint64_t(1) << 22;
    opt.max_triangles = std::uint64_t(1) << 18;
    opt.tessellate_cones = input.size() % 2 == 0;
    opt.cone_segments = 5;
    const io::BartResolver resolver = [&](const std::string&) -> std::optional<std::string> { return included; };
    auto scene = io::load_bart_from_string(text, "fuzz/scene.aff", resolver, opt);
    io::Frame f;
    const std::size_t n = scene->frame_count();
    if (n > 0) {
        scene->frame(0, f);
        scene->update(scene->frame_time(n - 1), f);
        if (n > 2) scene->frame(n / 2, f);
    }
    return f.triangles.size();
}

/// Loads or throws io::LoadError mentioning `name`: anything else fails the test.
template <class F>
void loads_or_load_error(const std::string& what, const std::string& name, F&& load) {
    CAPTURE(what);
    try {
        load();
    } catch (const io::LoadError& e) {
        CHECK(std::string(e.what()).find(name) != std::string::npos);
    } catch (const std::exception& e) {
        FAIL("not a LoadError: " << e.what());
    }
}

} // namespace

TEST_CASE("every seed of the fuzz corpus is a valid file") {
    if (!std::filesystem::is_directory(corpus_dir)) {
        MESSAGE("skipping: " << corpus_dir.string() << " is absent");
        return;
    }
    const auto ply = files_in("ply"), obj = files_in("obj"), bart = files_in("bart");
    CHECK(ply.size() >= 5);
    CHECK(obj.size() >= 3);
    CHECK(bart.size() >= 3);
    for (const auto& p : ply) {
        CAPTURE(p.string());
        const io::Mesh m = load_ply(slurp(p));
        CHECK(m.vertices.size() >= 2);
    }
    for (const auto& p : obj) {
        CAPTURE(p.string());
        const io::Mesh m = load_obj(slurp(p));
        CHECK(m.faces.size() >= 1);
    }
    for (const auto& p : bart) {
        CAPTURE(p.string());
        CHECK(load_bart(slurp(p)) >= 1);
    }
}

TEST_CASE("fuzzer regressions: inputs that once crashed load or throw LoadError") {
    // ply: (none found yet)
    // obj: (none found yet)
    // bart: (none found yet)
    struct Input {
        const char* what;
        std::string bytes;
    };
    const std::vector<Input> ply = {};
    const std::vector<Input> obj = {};
    const std::vector<Input> bart = {};
    for (const auto& in : ply) loads_or_load_error(in.what, "fuzz.ply", [&] { load_ply(in.bytes); });
    for (const auto& in : obj) loads_or_load_error(in.what, "fuzz.obj", [&] { load_obj(in.bytes); });
    for (const auto& in : bart) loads_or_load_error(in.what, "fuzz/", [&] { load_bart(in.bytes); });
}
