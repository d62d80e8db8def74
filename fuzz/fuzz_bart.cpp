// libFuzzer target for the BART loader (io/bart.hpp): any text either loads into a scene whose frames
// evaluate, or throws io::LoadError. Anything else (a crash, a sanitizer report, another exception) is
// a bug. The input is the entry file, optionally followed by a line "#@@" and the text every `i`
// include resolves to (`#` starts a comment, so the entry parses the same either way). Small limits
// keep every input fast. Build and run: fuzz/run.sh (or tools/fuzz.sh).
#include <dynbvh/io/bart.hpp>

#include <cstddef>
#include <cstdint>
#include <optional>
#include <string>
#include <string_view>

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
    const std::string input(reinterpret_cast<const char*>(data), size);
    const std::size_t cut = input.find("\n#@@\n");
    const std::string text = input.substr(0, cut);
    const std::string included = cut == std::string::npos ? std::string("p 3 0 0 0 1 0 0 0 1 0\n") : input.substr(cut + 5);
    dynbvh::io::BartOptions opt;
    opt.max_include_depth = 3;
    opt.max_includes = 16;
    opt.max_bytes = std::uint64_t(1) << 22;
    opt.max_triangles = std::uint64_t(1) << 18;
    opt.tessellate_cones = size % 2 == 0;
    opt.cone_segments = 5;
    const dynbvh::io::BartResolver resolver = [&](const std::string&) -> std::optional<std::string> { return included; };
    try {
        auto scene = dynbvh::io::load_bart_from_string(text, "fuzz/scene.aff", resolver, opt);
        dynbvh::io::Frame f;
        const std::size_t n = scene->frame_count();
        if (n > 0) {
            scene->frame(0, f);
            scene->update(scene->frame_time(n - 1), f);   // only what moved
            if (n > 2) scene->frame(n / 2, f);
            (void)scene->camera_at(scene->frame_time(n - 1));
            (void)scene->lights_at(scene->frame_time(n - 1));
        }
        if (!f.material.empty() && f.material.size() != f.triangles.size()) __builtin_trap();
        for (auto id : f.material)
            if (id >= scene->info().materials.size()) __builtin_trap();
    } catch (const dynbvh::io::LoadError&) {
    }
    return 0;
}
