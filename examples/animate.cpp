// dynbvh-animate: a BVH per frame of an animation, rebuilt or refitted, converted to a 4-wide tree
// and traced with one primary ray per pixel; prints per-frame timings and hit counts.
//
//   dynbvh-animate                                    a generated wobbling sphere, 16 frames, rebuilt
//   dynbvh-animate --mode refit --frames 64           PLOC at frame 0, refitted after (watch the SAH)
//   dynbvh-animate --input 'meshes/cloth_%03d.ply'    a PLY/OBJ frame sequence (pattern, directory or file)
//   dynbvh-animate --check 97                         also compare every 97th ray with a brute-force loop
#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <exception>
#include <memory>
#include <string>
#include <vector>

#include <CLI/CLI.hpp>

#include <dynbvh/intersect.hpp>
#include <dynbvh/io/frames.hpp>
#include <dynbvh/ploc.hpp>
#include <dynbvh/refit.hpp>
#include <dynbvh/sah.hpp>
#include <dynbvh/wide.hpp>

using namespace dynbvh;

namespace {

/// Frame `t` of a closed UV sphere (`rings` x 2 `rings` quads) whose radius wobbles with time and whose
/// centre swings along x. The poles are single vertices, so the mesh has no cracks.
std::vector<Trianglef> wobbling_sphere(int rings, double t) {
    const int segments = 2 * rings;
    const double pi = 3.14159265358979323846;
    auto vertex = [&](int i, int j) -> Vec3f {
        const double theta = pi * i / rings, phi = 2 * pi * (j % segments) / segments;
        const double r = 1 + 0.15 * std::sin(theta) * std::sin(3 * phi + 2 * t) * std::cos(4 * theta - t);
        const double cx = 0.5 * std::sin(0.5 * t);
        if (i == 0) return {float(cx), 1, 0};
        if (i == rings) return {float(cx), -1, 0};
        return {float(cx + r * std::sin(theta) * std::cos(phi)), float(r * std::cos(theta)), float(r * std::sin(theta) * std::sin(phi))};
    };
    std::vector<Trianglef> tris;
    for (int i = 0; i < rings; ++i)
        for (int j = 0; j < segments; ++j) {
            const Vec3f a = vertex(i, j), b = vertex(i + 1, j), c = vertex(i + 1, j + 1), d = vertex(i, j + 1);
            if (i + 1 < rings) tris.push_back({a, b, c});   // skip the two that collapse onto a pole
            if (i > 0) tris.push_back({a, c, d});
        }
    return tris;
}

/// Primary rays of a pinhole camera: pixel (x, y) of a w x h image, row 0 at the top.
struct Pinhole {
    Vec3f eye, forward, right, up;
    Pinhole(const io::Camera& c, int w, int h) : eye(c.from) {
        const float tan_half = std::tan(0.5f * c.fov_y_deg * 3.14159265f / 180.0f);
        forward = normalize(c.at - c.from);
        right = normalize(cross(forward, c.up)) * (tan_half * float(w) / float(h));
        up = normalize(cross(right, forward)) * tan_half;
    }
    Rayf ray(int x, int y, int w, int h) const {
        const float sx = 2 * (float(x) + 0.5f) / float(w) - 1, sy = 1 - 2 * (float(y) + 0.5f) / float(h);
        return {.org = eye, .dir = forward + right * sx + up * sy};
    }
};

double ms_since(std::chrono::steady_clock::time_point t0) {
    return std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - t0).count();
}

} // namespace

int main(int argc, char** argv) {
    // 1. Options: --x v and --x=v; --help exits 0, a bad value exits 2.
    std::string input, mode = "rebuild", res = "320x240";
    int frames = 16, threads = 0, rings = 64, check = 0;
    CLI::App app{"dynbvh-animate: rebuild or refit a BVH per frame, convert it to a wide tree, trace primary rays.", "dynbvh-animate"};
    app.add_option("--input", input, "PLY/OBJ frames: a printf pattern, a directory or one file (default: a generated sphere)")
        ->type_name("SPEC");
    app.add_option("--frames", frames, "at most this many frames (default 16)")->check(CLI::Range(1, 1 << 20))->type_name("N");
    app.add_option("--mode", mode, "rebuild | refit: rebuild every frame, or build frame 0 and refit after (default rebuild)")
        ->check(CLI::IsMember({"rebuild", "refit"}))
        ->type_name("M");
    app.add_option("--res", res, "image size (default 320x240)")->type_name("WxH");
    app.add_option("--threads", threads, "threads (default 0: all cores)")->check(CLI::Range(0, 4096))->type_name("N");
    app.add_option("--rings", rings, "the generated sphere's rings: 4 N^2 - 4 N triangles (default 64)")
        ->check(CLI::Range(2, 4096))
        ->type_name("N");
    app.add_option("--check", check, "compare every K-th ray with brute force over all triangles (default 0: off)")
        ->check(CLI::Range(0, 1 << 30))
        ->type_name("K");
    try {
        app.parse(argc, argv);
    } catch (const CLI::ParseError& e) {
        return app.exit(e) == 0 ? 0 : 2;   // help on stdout, or the error on stderr
    }
    int width = 0, height = 0;
    char tail = 0;
    if (std::sscanf(res.c_str(), "%dx%d%c", &width, &height, &tail) != 2 || width < 1 || height < 1 || width > 16384 || height > 16384) {
        std::fprintf(stderr, "--res: '%s' is not WIDTHxHEIGHT (1 to 16384 each)\n", res.c_str());
        return 2;
    }

    try {
        // 2. The frames: loaded in the background by io::open_frames, or generated here.
        std::unique_ptr<io::Scene> scene;
        io::Frame frame;
        if (!input.empty()) {
            scene = io::open_frames(input);
            frames = int(std::min<std::size_t>(std::size_t(frames), scene->frame_count()));
            scene->frame(0, frame);   // its camera frames the first frame
        } else {
            frame.triangles = wobbling_sphere(rings, 0);
            AABBf box;
            for (const auto& t : frame.triangles) box.extend(t.bounds());
            frame.camera = io::frame_bounds_camera(box);
        }
        const io::Camera camera = frame.camera;
        const Pinhole cam(camera, width, height);
        const exec::omp ex{.threads = threads};
        std::printf("%s, %d frames, %s, %dx%d, %d threads\n", input.empty() ? "wobbling sphere" : input.c_str(), frames, mode.c_str(),
                    width, height, ex.nthreads());
        std::printf("%5s %10s %10s %10s %10s %8s %10s\n", "frame", "triangles", "build ms", "wide ms", "trace ms", "SAH", "hits");

        Bvh<> bvh;
        std::size_t checked = 0, wrong = 0;
        for (int f = 0; f < frames; ++f) {
            if (!input.empty()) scene->frame(std::size_t(f), frame);
            else if (f > 0) frame.triangles = wobbling_sphere(rings, 0.25 * f);
            const std::span<const Trianglef> tris(frame.triangles);

            // 3. Rebuild (PLOC), or refit the tree of frame 0: same topology, boxes from the new positions.
            //    A refit needs the same triangles in the same order; a sequence that changes them is rebuilt.
            auto t0 = std::chrono::steady_clock::now();
            const bool refit_ok = mode == "refit" && f > 0 && bvh.primitive_count == tris.size();
            if (refit_ok) refit(bvh, tris, ex);
            else bvh = ploc::build(tris, {}, ex);
            const double build_ms = ms_since(t0);

            // 4. The 4-wide tree for tracing (the binary one stays, to be refitted next frame).
            t0 = std::chrono::steady_clock::now();
            const auto wide = make_wide<4>(bvh, ex);
            const double wide_ms = ms_since(t0);

            // 5. One closest-hit ray per pixel, rows in parallel.
            std::vector<std::size_t> row_hits(std::size_t(height), 0);
            t0 = std::chrono::steady_clock::now();
            ex.for_tasks(std::size_t(height), [&](std::size_t y) {
                for (int x = 0; x < width; ++x) row_hits[y] += bool(intersect(wide, tris, cam.ray(x, int(y), width, height)));
            });
            const double trace_ms = ms_since(t0);
            std::size_t hits = 0;
            for (std::size_t h : row_hits) hits += h;

            // 6. Optional: every check-th ray against all triangles; the closest t must match exactly.
            for (int p = 0; check > 0 && p < width * height; p += check) {
                const Rayf ray = cam.ray(p % width, p / width, width, height);
                Hitf best;
                for (const auto& t : tris)
                    if (const Hitf h = intersect_triangle(t, ray); h && h.t < best.t) best = h;
                const Hitf got = intersect(wide, tris, ray);
                ++checked;
                wrong += bool(got) != bool(best) || (got && got.t != best.t);
            }
            std::printf("%5d %10zu %10.3f %10.3f %10.3f %8.2f %10zu%s\n", f, tris.size(), build_ms, wide_ms, trace_ms,
                        sah_cost(bvh, {.ct = 3, .ci = 2}), hits, mode == "refit" && f > 0 && !refit_ok ? "  (rebuilt: triangles changed)" : "");
            if (hits == 0) throw std::runtime_error("frame " + std::to_string(f) + ": no ray hit the mesh");
        }
        if (check > 0) {
            std::printf("check: %zu rays compared with brute force, %zu differ\n", checked, wrong);
            if (wrong) return 1;
        }
        return 0;
    } catch (const std::exception& e) {
        std::fprintf(stderr, "dynbvh-animate: %s\n", e.what());
        return 1;
    }
}
