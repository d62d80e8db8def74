// The cost of robustness: nanoseconds per ray of closest-hit traversal with the robust and the fast box
// test (Ize 2013 vs plain slabs) and the watertight and the fast triangle test (Woop et al. 2013 vs
// Möller–Trumbore), in every combination, on the same tree and the same rays, one thread. Also the
// bare tests (ns per box or triangle test) outside traversal. Ratios from this very run are printed
// at the end; and the SIMD triangle-block tests (detail/triangle_block.hpp) on the same triangles.
//
//   dynbvh-bench-robustness [google benchmark flags]   (--help lists them)
//
// Scenes: a mid-animation frame of the built-in cloth-ball (~92k triangles) and the Stanford bunny
// (DYNBVH_DATA_DIR/meshes/bun_zipper.ply, when present). Trees: PLOC (radius 5), prim::indexed.
// Rays: "camera" = 256 x 256 primary rays from the scene's camera (coherent); "random" = 65536 rays
// from a sphere around the scene towards random points inside its box (incoherent; many graze).
// Counter per_ray: time per ray (the "n" suffix means nanoseconds).
#include <benchmark/benchmark.h>

#include <cmath>
#include <cstdint>
#include <cstdio>
#include <filesystem>
#include <map>
#include <memory>
#include <string>
#include <vector>

#include <dynbvh/detail/triangle_block.hpp>
#include <dynbvh/intersect.hpp>
#include <dynbvh/io/ply.hpp>
#include <dynbvh/ploc.hpp>
#include <scenes/builtin.hpp>
#include <dynbvh/traverse.hpp>

#include "cli.hpp"

namespace {

using namespace dynbvh;

struct Scene {
    std::vector<Trianglef> tris;
    Bvh<> bvh;
    std::vector<Rayf> camera_rays, random_rays;
};

std::uint64_t splitmix(std::uint64_t& s) {
    std::uint64_t z = (s += 0x9e3779b97f4a7c15ull);
    z = (z ^ (z >> 30)) * 0xbf58476d1ce4e5b9ull;
    z = (z ^ (z >> 27)) * 0x94d049bb133111ebull;
    return z ^ (z >> 31);
}
float uniform(std::uint64_t& s) { return float(splitmix(s) >> 40) * (1.0f / 16777216.0f); }

std::vector<Rayf> camera_rays(const io::Camera& cam, int w, int h) {
    const Vec3f fwd = normalize(cam.at - cam.from);
    const Vec3f right = normalize(cross(fwd, cam.up));
    const Vec3f up = cross(right, fwd);
    const float half = std::tan(0.5f * cam.fov_y_deg * 3.14159265f / 180.0f);
    std::vector<Rayf> rays;
    rays.reserve(std::size_t(w) * std::size_t(h));
    for (int y = 0; y < h; ++y)
        for (int x = 0; x < w; ++x) {
            const float px = (2 * (float(x) + 0.5f) / float(w) - 1) * half * float(w) / float(h);
            const float py = (1 - 2 * (float(y) + 0.5f) / float(h)) * half;
            rays.push_back({cam.from, normalize(fwd + right * px + up * py)});
        }
    return rays;
}

std::vector<Rayf> random_rays(const AABBf& b, std::size_t n) {
    std::uint64_t s = 12345;
    const Vec3f c = b.center();
    const float r = length(b.diagonal());
    std::vector<Rayf> rays(n);
    for (auto& ray : rays) {
        Vec3f d;
        do d = {2 * uniform(s) - 1, 2 * uniform(s) - 1, 2 * uniform(s) - 1};
        while (dot(d, d) > 1 || dot(d, d) < 1e-4f);
        const Vec3f target = b.min + b.diagonal() * Vec3f{uniform(s), uniform(s), uniform(s)};
        ray.org = c + normalize(d) * r;
        ray.dir = target - ray.org;
    }
    return rays;
}

Scene make_scene(std::vector<Trianglef> tris, const io::Camera& cam) {
    Scene s;
    s.tris = std::move(tris);
    s.bvh = ploc::build(std::span<const Trianglef>(s.tris), {.radius = 5});
    s.camera_rays = camera_rays(cam, 256, 256);
    s.random_rays = random_rays(s.bvh.bounds(), 65536);
    return s;
}

const std::string bunny_path = std::string(DYNBVH_DATA_DIR) + "/meshes/bun_zipper.ply";

const Scene& scene(int id) {
    static std::map<int, std::unique_ptr<Scene>> cache;
    auto& slot = cache[id];
    if (!slot) {
        if (id == 0) {
            auto sc = scenes::make_builtin("cloth-ball");
            io::Frame f;
            sc->frame(sc->frame_count() / 2, f);
            slot = std::make_unique<Scene>(make_scene(std::move(f.triangles), f.camera));
        } else {
            io::Mesh m = io::read_ply(bunny_path);
            auto tris = m.triangles();
            const io::Camera cam = io::frame_bounds_camera(m.bounds());
            slot = std::make_unique<Scene>(make_scene(std::move(tris), cam));
        }
    }
    return *slot;
}

void per_ray(benchmark::State& state, std::size_t rays) {
    state.counters["per_ray"] = benchmark::Counter(double(rays) * double(state.iterations()),
                                                   benchmark::Counter::kIsRate | benchmark::Counter::kInvert);
    state.SetItemsProcessed(std::int64_t(rays) * state.iterations());
}

/// Closest hit of every ray through the tree with Policy.
template <class Policy>
void BM_trace(benchmark::State& state, int scene_id, int ray_set) {
    const Scene& s = scene(scene_id);
    const auto& rays = ray_set == 0 ? s.camera_rays : s.random_rays;
    std::size_t hits = 0;
    for (auto _ : state) {
        hits = 0;
        for (const Rayf& r : rays) hits += intersect<Policy>(s.bvh, s.tris, r) ? 1 : 0;
        benchmark::DoNotOptimize(hits);
    }
    per_ray(state, rays.size());
    state.counters["hit%"] = 100.0 * double(hits) / double(rays.size());
}

/// The bare box test: every ray against 64 node boxes of the tree (prepared once per ray).
template <class Box>
void BM_box(benchmark::State& state) {
    const Scene& s = scene(0);
    const auto& rays = s.random_rays;
    std::vector<AABBf> boxes;
    for (std::size_t i = 0; i < s.bvh.nodes.size() && boxes.size() < 4096; i += s.bvh.nodes.size() / 4096 + 1)
        boxes.push_back(s.bvh.nodes[i].bounds());
    std::size_t n = 0, hit = 0;
    for (auto _ : state) {
        n = 0;
        hit = 0;
        for (std::size_t i = 0; i < rays.size(); i += 4) {
            const typename Box::template prepared<float> p(rays[i]);
            for (std::size_t k = 0; k < 64; ++k) {
                const AABBf& b = boxes[(i * 7 + k) % boxes.size()];
                float t;
                hit += Box::test(p, b.min, b.max, rays[i].tmax, t) ? 1 : 0;
                ++n;
            }
        }
        benchmark::DoNotOptimize(hit);
    }
    state.counters["per_test"] = benchmark::Counter(double(n) * double(state.iterations()),
                                                    benchmark::Counter::kIsRate | benchmark::Counter::kInvert);
    state.counters["hit%"] = 100.0 * double(hit) / double(n);
}

/// The bare triangle test: every ray against the 32 triangles of its neighbourhood in leaf order.
template <class Tri>
void BM_triangle(benchmark::State& state) {
    const Scene& s = scene(0);
    const auto& rays = s.camera_rays;
    std::vector<Trianglef> leaf_order;
    for (auto id : s.bvh.prim_ids) leaf_order.push_back(s.tris[id]);
    // Start each ray's run where its closest hit is, so that a realistic share of tests hits.
    std::vector<std::size_t> start(rays.size(), 0);
    std::vector<std::size_t> slot_of(s.tris.size(), 0);
    for (std::size_t k = 0; k < s.bvh.prim_ids.size(); ++k) slot_of[s.bvh.prim_ids[k]] = k;
    for (std::size_t i = 0; i < rays.size(); ++i) {
        const Hitf h = intersect(s.bvh, s.tris, rays[i]);
        start[i] = h ? (slot_of[h.prim] >= 16 ? slot_of[h.prim] - 16 : 0) : (i * 131) % leaf_order.size();
    }
    std::size_t n = 0, hit = 0;
    for (auto _ : state) {
        n = 0;
        hit = 0;
        for (std::size_t i = 0; i < rays.size(); i += 2) {
            const typename Tri::template prepared<float> p(rays[i]);
            for (std::size_t k = 0; k < 32; ++k) {
                float t, u, v;
                hit += Tri::test(p, leaf_order[(start[i] + k) % leaf_order.size()], rays[i].tmax, t, u, v) ? 1 : 0;
                ++n;
            }
        }
        benchmark::DoNotOptimize(hit);
    }
    state.counters["per_test"] = benchmark::Counter(double(n) * double(state.iterations()),
                                                    benchmark::Counter::kIsRate | benchmark::Counter::kInvert);
    state.counters["hit%"] = 100.0 * double(hit) / double(n);
}

/// The same 32 triangles per ray as BM_triangle, in 32 / L SIMD blocks of L lanes (detail/triangle_block.hpp),
/// through the block test traversal uses (per_test: per triangle, so directly comparable with BM_triangle).
template <class Tri, int L>
void BM_triangle_block(benchmark::State& state) {
    const Scene& s = scene(0);
    const auto& rays = s.camera_rays;
    std::vector<Trianglef> leaf_order;
    for (auto id : s.bvh.prim_ids) leaf_order.push_back(s.tris[id]);
    const std::size_t groups = leaf_order.size() / 32;   // runs of 32 slots, each 32 / L blocks
    std::vector<std::size_t> slot_of(s.tris.size(), 0);
    for (std::size_t k = 0; k < s.bvh.prim_ids.size(); ++k) slot_of[s.bvh.prim_ids[k]] = k;
    std::vector<std::size_t> start(rays.size(), 0);   // the run holding the closest hit (as BM_triangle)
    for (std::size_t i = 0; i < rays.size(); ++i) {
        const Hitf h = intersect(s.bvh, s.tris, rays[i]);
        start[i] = h ? std::min(slot_of[h.prim] / 32, groups - 1) : (i * 131) % groups;
    }
    std::vector<detail::LeafRange> runs(groups * (32 / L));
    for (std::size_t k = 0; k < runs.size(); ++k) runs[k] = {k * L, std::size_t(L)};
    std::vector<std::uint32_t> ids(leaf_order.size());
    for (std::size_t k = 0; k < ids.size(); ++k) ids[k] = std::uint32_t(k);
    scratch_vector<detail::TriangleBlock<L>> blocks;
    scratch_vector<std::size_t> first;
    detail::pack_triangle_blocks<L>(std::span<const detail::LeafRange>(runs), std::span<const std::uint32_t>(ids),
                                    [&](std::size_t slot) -> const Trianglef& { return leaf_order[slot]; }, blocks, first);
    std::size_t n = 0, hit = 0;
    for (auto _ : state) {
        n = 0;
        hit = 0;
        for (std::size_t i = 0; i < rays.size(); i += 2) {
            const detail::BlockTest<Tri, L> bt(rays[i]);
            float tmax = rays[i].tmax, tbox = tmax;
            std::uint32_t best = invalid_prim;
            Hitf h;
            bt.template test<false>(blocks.data(), start[i] * (32 / L), (start[i] + 1) * (32 / L), 1.0f, tmax, tbox, best, h);
            hit += best != invalid_prim ? 1 : 0;
            n += 32;
        }
        benchmark::DoNotOptimize(hit);
    }
    state.counters["per_test"] = benchmark::Counter(double(n) * double(state.iterations()),
                                                    benchmark::Counter::kIsRate | benchmark::Counter::kInvert);
    state.counters["hit%"] = 100.0 * double(hit) / double(n / 32);
}

using robust_box_watertight = trace::robust;
using fast_box_watertight = trace::policy<box::fast, tri::watertight>;
using robust_box_mt = trace::policy<box::robust, tri::moller_trumbore>;
using fast_box_mt = trace::fast;

/// Console output plus, at the end, the ratios of this run.
class RatioReporter : public benchmark::ConsoleReporter {
public:
    void ReportRuns(const std::vector<Run>& runs) override {
        ConsoleReporter::ReportRuns(runs);
        for (const Run& r : runs) {
            for (const char* c : {"per_ray", "per_test"}) {
                const auto it = r.counters.find(c);
                if (it != r.counters.end()) ns_[r.benchmark_name()] = double(it->second) * 1e9;
            }
        }
    }
    void Finalize() override {
        ConsoleReporter::Finalize();
        std::printf("\nCost of robustness (ns per ray, this run; ratio = robust / fast):\n");
        std::printf("%-22s %-8s %14s %14s %14s %14s %10s %10s\n", "scene", "rays", "robust+wt", "fast box+wt",
                    "robust box+MT", "fast+MT", "box cost", "tri cost");
        for (const char* sc : {"cloth-ball", "bunny"})
            for (const char* rs : {"camera", "random"}) {
                auto get = [&](const char* policy) {
                    const auto it = ns_.find(std::string("trace/") + policy + "/" + sc + "/" + rs);
                    return it == ns_.end() ? -1.0 : it->second;
                };
                const double a = get("robust_box+watertight"), b = get("fast_box+watertight"), c = get("robust_box+MT"),
                             d = get("fast_box+MT");
                if (a < 0) continue;
                std::printf("%-22s %-8s %14.1f %14.1f %14.1f %14.1f %9.2fx %9.2fx\n", sc, rs, a, b, c, d, a / b, a / c);
            }
        auto ratio = [&](const char* x, const char* y) {
            const auto i = ns_.find(x), j = ns_.find(y);
            if (i != ns_.end() && j != ns_.end())
                std::printf("%-34s %8.2f ns vs %8.2f ns: %.2fx\n", x, i->second, j->second, i->second / j->second);
        };
        std::printf("\nBare tests (ns per test; robust vs fast):\n");
        ratio("box/robust", "box/fast");
        ratio("triangle/watertight", "triangle/moller_trumbore");
        std::printf("\nSIMD triangle blocks (ns per triangle; block vs one at a time):\n");
        ratio("triangle/watertight blocks8", "triangle/watertight");
        ratio("triangle/watertight blocks4", "triangle/watertight");
        ratio("triangle/moller_trumbore blocks8", "triangle/moller_trumbore");
        ratio("triangle/moller_trumbore blocks4", "triangle/moller_trumbore");
        std::printf("box cost = (robust box + watertight) / (fast box + watertight); tri cost = (robust box + watertight) "
                    "/ (robust box + Möller–Trumbore)\n");
    }

private:
    std::map<std::string, double> ns_;
};

void register_all() {
    const bool bunny = std::filesystem::exists(bunny_path);
    auto add = [&](const char* policy, void (*fn)(benchmark::State&, int, int)) {
        for (int sc = 0; sc < (bunny ? 2 : 1); ++sc)
            for (int rs = 0; rs < 2; ++rs) {
                const std::string name = std::string("trace/") + policy + "/" + (sc == 0 ? "cloth-ball" : "bunny") + "/" +
                                         (rs == 0 ? "camera" : "random");
                benchmark::RegisterBenchmark(name.c_str(), fn, sc, rs)->Unit(benchmark::kMillisecond);
            }
    };
    add("robust_box+watertight", BM_trace<robust_box_watertight>);
    add("fast_box+watertight", BM_trace<fast_box_watertight>);
    add("robust_box+MT", BM_trace<robust_box_mt>);
    add("fast_box+MT", BM_trace<fast_box_mt>);
    benchmark::RegisterBenchmark("box/robust", BM_box<box::robust>)->Unit(benchmark::kMillisecond);
    benchmark::RegisterBenchmark("box/fast", BM_box<box::fast>)->Unit(benchmark::kMillisecond);
    benchmark::RegisterBenchmark("triangle/watertight", BM_triangle<tri::watertight>)->Unit(benchmark::kMillisecond);
    benchmark::RegisterBenchmark("triangle/moller_trumbore", BM_triangle<tri::moller_trumbore>)->Unit(benchmark::kMillisecond);
    benchmark::RegisterBenchmark("triangle/watertight blocks8", BM_triangle_block<tri::watertight, 8>)->Unit(benchmark::kMillisecond);
    benchmark::RegisterBenchmark("triangle/watertight blocks4", BM_triangle_block<tri::watertight, 4>)->Unit(benchmark::kMillisecond);
    benchmark::RegisterBenchmark("triangle/moller_trumbore blocks8", BM_triangle_block<tri::moller_trumbore, 8>)->Unit(benchmark::kMillisecond);
    benchmark::RegisterBenchmark("triangle/moller_trumbore blocks4", BM_triangle_block<tri::moller_trumbore, 4>)->Unit(benchmark::kMillisecond);
    if (!bunny) std::fprintf(stderr, "dynbvh-bench-robustness: %s is absent, bunny skipped\n", bunny_path.c_str());
}

} // namespace

int main(int argc, char** argv) {
    CLI::App app{"dynbvh-bench-robustness: ns per ray of the robust vs fast box and triangle tests (no options of its own).",
                 "dynbvh-bench-robustness"};
    if (const auto rc = cli::parse_with_benchmark_flags(app, argc, argv)) return *rc;
    register_all();
    benchmark::Initialize(&argc, argv);
    if (benchmark::ReportUnrecognizedArguments(argc, argv)) return 1;
    RatioReporter reporter;
    benchmark::RunSpecifiedBenchmarks(&reporter);
    benchmark::Shutdown();
    return 0;
}
