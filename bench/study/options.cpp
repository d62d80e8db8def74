#include "options.hpp"

#include <charconv>
#include <cmath>
#include <cstdint>
#include <stdexcept>

#include <cli.hpp>

namespace dynbvh::study {

std::vector<std::string> split_list(const std::string& s, char sep) {
    std::vector<std::string> out;
    std::string cur;
    for (char c : s) {
        if (c == sep) {
            if (!cur.empty()) out.push_back(cur);
            cur.clear();
        } else {
            cur += c;
        }
    }
    if (!cur.empty()) out.push_back(cur);
    return out;
}

Resolution parse_resolution(const std::string& s) {
    const auto x = s.find('x');
    auto dim = [&](const std::string& v) {
        int d = 0;
        const char* end = v.data() + v.size();
        const auto r = std::from_chars(v.data(), end, d);
        if (v.empty() || r.ec != std::errc() || r.ptr != end) throw std::invalid_argument("--res: '" + s + "' is not WIDTHxHEIGHT");
        return d;
    };
    if (x == std::string::npos) throw std::invalid_argument("--res: '" + s + "' is not WIDTHxHEIGHT");
    Resolution r{dim(s.substr(0, x)), dim(s.substr(x + 1))};
    if (r.width <= 0 || r.height <= 0 || r.width > 16384 || r.height > 16384)
        throw std::invalid_argument("--res: '" + s + "' must be between 1x1 and 16384x16384");
    return r;
}

namespace {

const char* const description =
    "dynbvh-study: the thesis's BVH study (build + trace per frame, FPS, SAH) on any scene, beside Embree.\n"
    "dynbvh-study --info SCENE describes one scene as JSON and exits.";

const char* const footer = R"(Scenes (--scenes, comma separated; default: every built-in scene)
  cloth-ball, n-body, breaking, large-breaking, funnel   built-in scenes (generated in memory)
  mesh.ply, mesh.obj                                      one file = one frame
  dir/cloth_%03d.ply                                      printf-style frame pattern
  dir/                                                    every .ply/.obj in a directory, natural order
  kitchen.aff                                             BART scene

Builders (--builders, comma separated; default: all available)
  lbvh, kbvh (presplit + PLOC), ploc (r = 5), binned-sah, refit, refit:lbvh (PLOC or LBVH at frame 0, refitted after),
  morton-wide (the wide tree straight from the sorted Morton codes, leaves in SIMD triangle blocks; no
  binary tree, so no SAH column), embree-low, embree-medium, embree-refit (when built with Embree 3)
  auto, auto:lbvh (strategy dynbvh::Dynamic: refit each frame, rebuild with PLOC or LBVH once the trace time
  refitting lost since the last rebuild reaches a rebuild's time; knobs rule=sah (rebuild past th x the last
  rebuild's SAH instead), th=1.3, async=1 (rebuild in the background, swap when ready), r=, bits=)
  two-level, two-level:lbvh (dynbvh::TwoLevel: one tree per rigid body of the frame (the objects sharing
  a BART transform node, all static objects together), built once and placed by its transform, refitted or
  rebuilt for deforming objects (th=), a top-level tree rebuilt every frame; scenes whose frames expose no
  objects are skipped)
  embree-two-level (Embree 3 instancing over the same bodies: one scene each, an instance each, a top scene
  per frame)
  Knobs after a colon: ploc:r=16, kbvh:beta=0.2, lbvh:bits=63, ploc:leaf=4, binned-sah:bins=16,
  ploc:tri=mt (Moller-Trumbore instead of watertight), ploc:box=fast (plain slab test),
  ploc:prim=pre (leaf triangles copied into the tree), ploc:wide=4 / ploc:wide=8 (trace a 4- or 8-wide
  tree converted from the binary one; default 8 when built with AVX, else 4), ploc:wide=0 (the binary
  tree), ploc:blocks=1 / ploc:blocks=0 (the wide tree's leaves in SIMD triangle blocks, the binary tree
  built with fuller leaves for them, the default; or index leaves), e.g. ploc:r=10:leaf=4

Options take their value as --x V or --x=V.

Output (in --out): study.json and study.csv (every frame's measurement, machine, compiler, backend,
threads), report.md with SVG plots and PNG renders; tables like the thesis's Tables 5.2-5.5 on stdout.
)";

/// The values as typed, where they need more than CLI11's conversion (lists, presets, cross checks).
struct Raw {
    std::string scenes, builders, res, sweep_scenes, backend, effects, out, rays;
    bool no_warmup = false;
};

/// `text` broken into lines of at most ~72 characters, continued under CLI11's description column.
std::string wrap(const std::string& text) {
    std::string out, line;
    for (const auto& word : split_list(text, ' ')) {
        if (!line.empty() && line.size() + 1 + word.size() > 72) {
            out += line + "\n" + std::string(30, ' ');
            line.clear();
        }
        line += (line.empty() ? "" : " ") + word;
    }
    return out + line;
}

void define(CLI::App& app, Options& o, Raw& raw) {
    using cli::number_in;
    cli::take_last(app);
    app.footer(footer);
    app.add_option("--scenes", raw.scenes, "scenes, comma separated (see below; default: every built-in scene)")->type_name("LIST");
    app.add_option("--builders", raw.builders, "builders, comma separated (see below; default: all available)")->type_name("LIST");
    app.add_option("--res", raw.res, "resolutions (default 854x480,1920x1080,3840x2160)")->type_name("WxH,...");
    app.add_option("--reps", o.reps, "repetitions (default 1; --full: 10)")->type_name("N")->check(number_in(1, 1000));
    app.add_option("--frames", o.frames, "at most N frames per scene (default all)")
        ->type_name("N")
        ->check(number_in<std::size_t>(1, SIZE_MAX));
    app.add_option("--frame-step", o.frame_step, "use every K-th frame (default 1)")
        ->type_name("K")
        ->check(number_in<std::size_t>(1, SIZE_MAX));
    app.add_option("--threads", o.threads, "worker threads (default 0: all cores)")->type_name("N")->check(number_in(0, 4096));
    app.add_option("--backend", raw.backend, "tbb | omp | serial (default tbb when built with it: Embree shares its workers)")
        ->type_name("B");
    app.add_option("--out", raw.out, "output directory (default out/study)")->type_name("DIR");
    app.add_option("--scale", o.scale, "built-in scenes' triangle-count scale, 0 < S <= 16 (default 1)")
        ->type_name("S")
        ->check(number_in(0.0, 16.0));
    app.add_option("--seed", o.seed, "built-in scenes' seed (default 1)")
        ->type_name("N")
        ->check(number_in<std::uint64_t>(0, UINT64_MAX));
    app.add_option("--images", o.images, "frames rendered to PNG per scene (default 3; 0: none)")
        ->type_name("N")
        ->check(number_in<std::size_t>(0, SIZE_MAX));
    app.add_option("--cache-mb", o.cache_mb, "keep generated frames in memory up to N MiB (default 2048)")
        ->type_name("N")
        ->check(number_in<std::size_t>(0, SIZE_MAX));
    app.add_flag("--no-warmup", raw.no_warmup, "skip the untimed warm-up build + trace per builder");
    app.add_option("--effects", raw.effects,
                   wrap("primary (default): one primary ray per pixel, the thesis's protocol; auto: after the primary trace, render "
                   "every frame Whitted-style with the effects the scene calls for (shadow rays towards its lights, reflection "
                   "rays from specular or transparent materials, refraction rays from transparent ones) and report rays and "
                   "trace time per effect; the PNG renders then show those effects"))
        ->type_name("E");
    app.add_option("--rays", raw.rays,
                   wrap("packet (default): primary rays traced in packets (dynbvh's packet traversal: 32 rays = 8x4 pixels on "
                   "wide trees and two-level scenes; rtcIntersect16 on 4x4 pixels for Embree); single: one ray at a "
                   "time (intersect, rtcIntersect1)"))
        ->type_name("R");
    app.add_option("--effects-depth", o.effects_depth, "most reflection/refraction bounces with --effects auto (default 5)")
        ->type_name("N")
        ->check(number_in(0, 64));
    app.add_flag("--quick", o.quick,
                 wrap("every built-in scene at scale 0.1, all builders, 8 frames spread over each animation, 427x240 and 854x480, "
                 "a small sweep on cloth-ball (3 repetitions): under 3 minutes on 2 cores"));
    app.add_flag("--full", o.full, "the thesis protocol: full scale, all frames, 3 resolutions, 10 repetitions");
    app.add_flag("--sweep", o.sweep,
                 wrap("after the study, measure what accuracy costs in time (PLOC radius, presplit budget, Morton bits, leaf size, "
                 "triangle and box tests) and where each setting starts to win"));
    app.add_flag("--sweep-only", o.sweep_only, "only the sweep");
    app.add_option("--sweep-scenes", raw.sweep_scenes, "scenes of the sweep (default: the study's scenes)")->type_name("LIST");
    app.add_option("--sweep-reps", o.sweep_reps, "repetitions of the sweep (default: --reps; --quick: 3)")
        ->type_name("N")
        ->check(number_in(1, 1000));
    app.add_option("--info", o.info, "print one JSON object describing SCENE and exit")->type_name("SCENE");
}

} // namespace

std::string usage() {
    CLI::App app{description, "dynbvh-study"};
    Options o;
    Raw raw;
    define(app, o, raw);
    return app.help();
}

Options parse_options(int argc, char** argv) {
    Options o;
    for (int i = 0; i < argc; ++i) {
        if (i) o.command_line += ' ';
        o.command_line += argv[i];
    }
    CLI::App app{description, "dynbvh-study"};
    Raw raw;
    define(app, o, raw);
    try {
        app.parse(argc, argv);
    } catch (const CLI::ParseError& e) {
        if (e.get_exit_code() == 0) {
            o.help = true;
            return o;
        }
        throw std::invalid_argument(e.what());
    }
    const auto given = [&](const char* name) { return app.count(name) > 0; };
    // Lists, choices and checks across options.
    if (given("--scenes")) o.scenes = split_list(raw.scenes);
    if (given("--builders")) o.builders = split_list(raw.builders);
    if (given("--sweep-scenes")) o.sweep_scenes = split_list(raw.sweep_scenes);
    if (given("--res")) {
        o.resolutions.clear();
        for (const auto& r : split_list(raw.res)) o.resolutions.push_back(parse_resolution(r));
        if (o.resolutions.empty()) throw std::invalid_argument("--res: no resolution given");
    }
    if (given("--backend")) {
        o.backend = raw.backend;
        if (o.backend != "omp" && o.backend != "tbb" && o.backend != "serial")
            throw std::invalid_argument("--backend must be omp, tbb or serial, not '" + o.backend + "'");
    }
    if (given("--out")) {
        if (raw.out.empty()) throw std::invalid_argument("--out needs a directory");
        o.out = raw.out;
    }
    if (!(o.scale > 0)) throw std::invalid_argument("--scale must be in (0, 16]");
    if (given("--effects")) {
        if (raw.effects != "auto" && raw.effects != "primary")
            throw std::invalid_argument("--effects must be auto or primary, not '" + raw.effects + "'");
        o.effects = raw.effects == "auto";
    }
    if (given("--rays")) {
        if (raw.rays != "packet" && raw.rays != "single")
            throw std::invalid_argument("--rays must be packet or single, not '" + raw.rays + "'");
        o.packets = raw.rays == "packet";
    }
    if (raw.no_warmup) o.warmup = false;
    if (o.sweep_only) o.sweep = true;
    if (o.quick && o.full) throw std::invalid_argument("--quick and --full exclude each other");
    // Presets fill only what the user did not set.
    if (o.quick) {
        if (!given("--scale")) o.scale = 0.1;
        if (!given("--res")) o.resolutions = {{427, 240}, {854, 480}};
        if (!given("--frames")) o.frames = 8;
        if (!given("--frame-step")) o.frame_step = 0;   // 0: spread the frames over the whole animation
        if (!given("--reps")) o.reps = 1;
        if (!o.sweep) {
            o.sweep = true;
            o.sweep_small = true;
            if (o.sweep_scenes.empty()) o.sweep_scenes = {"cloth-ball"};
            if (o.sweep_reps == 0) o.sweep_reps = 3;
        }
    }
    if (o.full) {
        if (!given("--reps")) o.reps = 10;
    }
    return o;
}

} // namespace dynbvh::study
