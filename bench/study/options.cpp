#include "options.hpp"

#include <charconv>
#include <cmath>
#include <stdexcept>

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

namespace {

template <class T>
T parse_number(const std::string& opt, const std::string& v) {
    T x{};
    const char* end = v.data() + v.size();
    const auto r = std::from_chars(v.data(), end, x);
    if (v.empty() || r.ec != std::errc() || r.ptr != end)
        throw std::invalid_argument(opt + ": '" + v + "' is not a valid number");
    return x;
}

} // namespace

Resolution parse_resolution(const std::string& s) {
    const auto x = s.find('x');
    if (x == std::string::npos) throw std::invalid_argument("--res: '" + s + "' is not WIDTHxHEIGHT");
    Resolution r{parse_number<int>("--res", s.substr(0, x)), parse_number<int>("--res", s.substr(x + 1))};
    if (r.width <= 0 || r.height <= 0 || r.width > 16384 || r.height > 16384)
        throw std::invalid_argument("--res: '" + s + "' must be between 1x1 and 16384x16384");
    return r;
}

std::string usage() {
    return R"(dynbvh-study: the thesis's BVH study (build + trace per frame, FPS, SAH) on any scene, beside Embree.

Usage: dynbvh-study [options]
       dynbvh-study --info SCENE

Scenes (--scenes, comma separated; default: every built-in scene)
  cloth-ball, n-body, breaking, large-breaking, funnel   built-in scenes (generated in memory)
  mesh.ply, mesh.obj                                      one file = one frame
  dir/cloth_%03d.ply                                      printf-style frame pattern
  dir/                                                    every .ply/.obj in a directory, natural order
  kitchen.aff                                             BART scene

Builders (--builders, comma separated; default: all available)
  lbvh, kbvh (presplit + PLOC), ploc (r = 5), binned-sah, refit (LBVH at frame 0, refitted after),
  embree-low, embree-medium, embree-refit (when built with Embree 3)
  Knobs after a colon: ploc:r=16, kbvh:beta=0.2, lbvh:bits=63, ploc:leaf=4, binned-sah:bins=16,
  ploc:tri=mt (Moller-Trumbore instead of watertight), ploc:box=fast (plain slab test),
  ploc:prim=pre (leaf triangles copied into the tree), ploc:wide=4 / ploc:wide=8 (trace a 4- or 8-wide
  tree converted from the binary one; default 8 when built with AVX, else 4), ploc:wide=0 (the binary
  tree), e.g. ploc:r=10:leaf=4

Options
  --res WxH,...        resolutions (default 854x480,1920x1080,3840x2160)
  --reps N             repetitions (default 1; --full: 10)
  --frames N           at most N frames per scene (default all)
  --frame-step K       use every K-th frame (default 1)
  --threads N          worker threads (default: all cores)
  --backend B          tbb | omp | serial (default tbb when built with it: Embree shares its workers)
  --out DIR            output directory (default out/study)
  --scale S            built-in scenes' triangle-count scale, 0 < S <= 16 (default 1)
  --seed N             built-in scenes' seed (default 1)
  --images N           frames rendered to PNG per scene (default 3; 0: none)
  --cache-mb N         keep generated frames in memory up to N MiB (default 2048)
  --no-warmup          skip the untimed warm-up build + trace per builder
  --effects E          primary (default): one primary ray per pixel, the thesis's protocol;
                       auto: after the primary trace, render every frame Whitted-style with the effects the
                       scene calls for (shadow rays towards its lights, reflection rays from specular or
                       transparent materials, refraction rays from transparent ones) and report rays and
                       trace time per effect; the PNG renders then show those effects
  --effects-depth N    most reflection/refraction bounces with --effects auto (default 5)
  --quick              every built-in scene at scale 0.1, all builders, 8 frames spread over each animation,
                       427x240 and 854x480, a small sweep on cloth-ball (3 repetitions): under 3 minutes on 2 cores
  --full               the thesis protocol: full scale, all frames, 3 resolutions, 10 repetitions
  --sweep              after the study, measure what accuracy costs in time (PLOC radius, presplit budget,
                       Morton bits, leaf size, triangle and box tests) and where each setting starts to win
  --sweep-only         only the sweep
  --sweep-scenes LIST  scenes of the sweep (default: the study's scenes)
  --sweep-reps N       repetitions of the sweep (default: --reps; --quick: 3)
  --info SCENE         print one JSON object describing SCENE and exit
  --help

Output (in --out): study.json and study.csv (every frame's measurement, machine, compiler, backend,
threads), report.md with SVG plots and PNG renders; tables like the thesis's Tables 5.2-5.5 on stdout.
)";
}

Options parse_options(int argc, char** argv) {
    Options o;
    for (int i = 0; i < argc; ++i) {
        if (i) o.command_line += ' ';
        o.command_line += argv[i];
    }
    bool res_given = false, reps_given = false, frames_given = false, scale_given = false, step_given = false;
    auto value = [&](int& i, const std::string& opt) -> std::string {
        if (i + 1 >= argc) throw std::invalid_argument(opt + " needs a value");
        return argv[++i];
    };
    for (int i = 1; i < argc; ++i) {
        std::string a = argv[i];
        std::string inline_value;
        bool has_inline = false;
        if (a.rfind("--", 0) == 0) {
            const auto eq = a.find('=');
            if (eq != std::string::npos) {
                inline_value = a.substr(eq + 1);
                a = a.substr(0, eq);
                has_inline = true;
            }
        }
        auto val = [&]() { return has_inline ? inline_value : value(i, a); };
        if (a == "--help" || a == "-h") o.help = true;
        else if (a == "--scenes") o.scenes = split_list(val());
        else if (a == "--builders") o.builders = split_list(val());
        else if (a == "--res") {
            o.resolutions.clear();
            for (const auto& r : split_list(val())) o.resolutions.push_back(parse_resolution(r));
            if (o.resolutions.empty()) throw std::invalid_argument("--res: no resolution given");
            res_given = true;
        } else if (a == "--reps") {
            o.reps = parse_number<int>(a, val());
            if (o.reps < 1 || o.reps > 1000) throw std::invalid_argument("--reps must be between 1 and 1000");
            reps_given = true;
        } else if (a == "--frames") {
            o.frames = parse_number<std::size_t>(a, val());
            if (o.frames == 0) throw std::invalid_argument("--frames must be at least 1");
            frames_given = true;
        } else if (a == "--frame-step") {
            o.frame_step = parse_number<std::size_t>(a, val());
            if (o.frame_step == 0) throw std::invalid_argument("--frame-step must be at least 1");
            step_given = true;
        } else if (a == "--threads") {
            o.threads = parse_number<int>(a, val());
            if (o.threads < 0 || o.threads > 4096) throw std::invalid_argument("--threads must be between 0 and 4096");
        } else if (a == "--backend") {
            o.backend = val();
            if (o.backend != "omp" && o.backend != "tbb" && o.backend != "serial")
                throw std::invalid_argument("--backend must be omp, tbb or serial, not '" + o.backend + "'");
        } else if (a == "--out") {
            o.out = val();
            if (o.out.empty()) throw std::invalid_argument("--out needs a directory");
        } else if (a == "--scale") {
            o.scale = parse_number<double>(a, val());
            if (!(o.scale > 0 && o.scale <= 16)) throw std::invalid_argument("--scale must be in (0, 16]");
            scale_given = true;
        } else if (a == "--seed") o.seed = parse_number<std::uint64_t>(a, val());
        else if (a == "--images") o.images = parse_number<std::size_t>(a, val());
        else if (a == "--cache-mb") o.cache_mb = parse_number<std::size_t>(a, val());
        else if (a == "--no-warmup") o.warmup = false;
        else if (a == "--effects") {
            const std::string e = val();
            if (e != "auto" && e != "primary") throw std::invalid_argument("--effects must be auto or primary, not '" + e + "'");
            o.effects = e == "auto";
        } else if (a == "--effects-depth") {
            o.effects_depth = parse_number<int>(a, val());
            if (o.effects_depth < 0 || o.effects_depth > 64) throw std::invalid_argument("--effects-depth must be between 0 and 64");
        }
        else if (a == "--quick") o.quick = true;
        else if (a == "--full") o.full = true;
        else if (a == "--sweep") o.sweep = true;
        else if (a == "--sweep-only") o.sweep = o.sweep_only = true;
        else if (a == "--sweep-scenes") o.sweep_scenes = split_list(val());
        else if (a == "--sweep-reps") {
            o.sweep_reps = parse_number<int>(a, val());
            if (o.sweep_reps < 1 || o.sweep_reps > 1000) throw std::invalid_argument("--sweep-reps must be between 1 and 1000");
        }
        else if (a == "--info") o.info = val();
        else throw std::invalid_argument("unknown option '" + a + "' (see --help)");
    }
    if (o.quick && o.full) throw std::invalid_argument("--quick and --full exclude each other");
    // Presets fill only what the user did not set.
    if (o.quick) {
        if (!scale_given) o.scale = 0.1;
        if (!res_given) o.resolutions = {{427, 240}, {854, 480}};
        if (!frames_given) o.frames = 8;
        if (!step_given) o.frame_step = 0;   // 0: spread the frames over the whole animation
        if (!reps_given) o.reps = 1;
        if (!o.sweep) {
            o.sweep = true;
            o.sweep_small = true;
            if (o.sweep_scenes.empty()) o.sweep_scenes = {"cloth-ball"};
            if (o.sweep_reps == 0) o.sweep_reps = 3;
        }
    }
    if (o.full) {
        if (!reps_given) o.reps = 10;
    }
    return o;
}

} // namespace dynbvh::study
