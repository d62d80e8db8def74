// Build time of every dynbvh builder next to Embree 3 (LOW, MEDIUM) on the same triangles with the
// same thread count, in one run, so every figure reads as a ratio. Scenes (benchmark argument 0, 1, 2):
// a ~92k-triangle frame of the built-in cloth-ball, a ~1.6M-triangle frame of large-breaking, and the
// 99k long thin triangles of scenes/lattice.hpp. The traced layout (BM_*_blocks: 8-wide nodes with
// leaves in SIMD blocks of 8) from each builder, and from morton_wide (the wide tree straight from the
// sorted Morton codes; BM_morton_wide8_blocks: morton_wide::build_blocks, leaves packed as they are made;
// BM_ploc_r5_blocks: ploc::build_blocks, the tree of BM_ploc_r5_wide8_blocks in one step, with the default hierarchical
// schedule (H-PLOC), BM_ploc_r5_global_blocks with the original one; BM_kbvh_blocks likewise). Each builder three ways: the
// binary Bvh (BM_<builder>), binary + make_wide<8> (BM_<builder>_then_wide8) and direct wide emission
// build_wide<8> (BM_<builder>_wide8; the same tree, the 8-wide layout the study traces); refit of the
// binary and of the 8-wide LBVH tree (BM_refit_binary, BM_refit_wide8) beside Embree's REFIT.
//
//   dynbvh-bench-build [--threads N] [google benchmark flags]   (default: 2 threads, as in CI; --threads=N too)
//
// Counters: tris (triangles), Mtris/s, SAH (Ct = 3, Ci = 2, dynbvh trees only).
#include <benchmark/benchmark.h>

#include <map>
#include <memory>
#include <string>

#include <dynbvh/binned_sah.hpp>
#include <dynbvh/kbvh.hpp>
#include <dynbvh/lbvh.hpp>
#include <dynbvh/morton_wide.hpp>
#include <dynbvh/ploc.hpp>
#include <dynbvh/refit.hpp>
#include <dynbvh/sah.hpp>
#include <dynbvh/wide.hpp>
#include <dynbvh/wide_blocks.hpp>
#include <scenes/builtin.hpp>
#include <scenes/lattice.hpp>

#include "cli.hpp"
#include "embree_bvh.hpp"

namespace {

using namespace dynbvh;

int g_threads = 2;

const std::vector<Trianglef>& scene_triangles(const std::string& name) {
    static std::map<std::string, std::vector<Trianglef>> cache;
    auto it = cache.find(name);
    if (it != cache.end()) return it->second;
    io::Frame f;
    if (name == "lattice") {
        f = scenes::lattice();   // long thin crossing beams (scenes/lattice.hpp)
    } else {
        auto scene = scenes::make_builtin(name);
        scene->frame(scene->frame_count() / 2, f);   // a mid-animation frame: the cloth draped, the pieces flying
    }
    return cache.emplace(name, std::move(f.triangles)).first->second;
}

const char* scene_of(std::int64_t arg) { return arg == 0 ? "cloth-ball" : arg == 1 ? "large-breaking" : "lattice"; }

template <class Build>
void run_dynbvh(benchmark::State& state, Build&& build) {
    const auto& tris = scene_triangles(scene_of(state.range(0)));
    exec::default_executor ex{};
#if defined(_OPENMP)
    ex.threads = g_threads;
#endif
    auto bvh = build(tris, ex);   // warm-up: faults in the scratch memory reused by every later frame
    for (auto _ : state) {
        bvh = build(tris, ex);
        benchmark::DoNotOptimize(bvh.nodes.data());
    }
    state.counters["tris"] = double(tris.size());
    state.counters["Mtris/s"] = benchmark::Counter(double(tris.size()) * double(state.iterations()) * 1e-6,
                                                   benchmark::Counter::kIsRate);
    state.counters["SAH"] = sah_cost(bvh, {.ct = 3, .ci = 2});
}

void BM_lbvh(benchmark::State& s) { run_dynbvh(s, [](const auto& t, const auto& ex) { return lbvh::build(t, {}, ex); }); }
void BM_lbvh63(benchmark::State& s) { run_dynbvh(s, [](const auto& t, const auto& ex) { return lbvh::build(t, {.morton_bits = 63}, ex); }); }
void BM_ploc_r5(benchmark::State& s) { run_dynbvh(s, [](const auto& t, const auto& ex) { return ploc::build(t, {.radius = 5}, ex); }); }
void BM_ploc_r32(benchmark::State& s) { run_dynbvh(s, [](const auto& t, const auto& ex) { return ploc::build(t, {.radius = 32}, ex); }); }
void BM_kbvh(benchmark::State& s) { run_dynbvh(s, [](const auto& t, const auto& ex) { return kbvh::build(t, {}, ex); }); }
void BM_binned_sah(benchmark::State& s) { run_dynbvh(s, [](const auto& t, const auto& ex) { return binned_sah::build(t, {}, ex); }); }

// The 8-wide (traced) layout: direct emission, and binary build + make_wide<8> (same tree).
void BM_lbvh_wide8(benchmark::State& s) { run_dynbvh(s, [](const auto& t, const auto& ex) { return lbvh::build_wide<8>(t, {}, ex); }); }
void BM_lbvh_then_wide8(benchmark::State& s) { run_dynbvh(s, [](const auto& t, const auto& ex) { return make_wide<8>(lbvh::build(t, {}, ex), ex); }); }
void BM_ploc_r5_wide8(benchmark::State& s) { run_dynbvh(s, [](const auto& t, const auto& ex) { return ploc::build_wide<8>(t, {.radius = 5}, ex); }); }
void BM_ploc_r5_then_wide8(benchmark::State& s) { run_dynbvh(s, [](const auto& t, const auto& ex) { return make_wide<8>(ploc::build(t, {.radius = 5}, ex), ex); }); }
void BM_kbvh_wide8(benchmark::State& s) { run_dynbvh(s, [](const auto& t, const auto& ex) { return kbvh::build_wide<8>(t, {}, ex); }); }
void BM_kbvh_then_wide8(benchmark::State& s) { run_dynbvh(s, [](const auto& t, const auto& ex) { return make_wide<8>(kbvh::build(t, {}, ex), ex); }); }
void BM_binned_sah_wide8(benchmark::State& s) { run_dynbvh(s, [](const auto& t, const auto& ex) { return binned_sah::build_wide<8>(t, {}, ex); }); }
void BM_binned_sah_then_wide8(benchmark::State& s) { run_dynbvh(s, [](const auto& t, const auto& ex) { return make_wide<8>(binned_sah::build(t, {}, ex), ex); }); }

// The traced layout (8-wide nodes, leaves in SIMD blocks of 8, wide_blocks.hpp) straight from each
// builder: direct wide emission with leaves sized for blocks, then packing; morton_wide (morton_wide.hpp)
// without blocks, with blocks in one step (build_blocks) and the same tree packed after (make_wide_blocks).
void BM_morton_wide8(benchmark::State& s) { run_dynbvh(s, [](const auto& t, const auto& ex) { return morton_wide::build<8>(std::span<const Trianglef>(t), {}, ex); }); }
void BM_morton_wide8_blocks(benchmark::State& s) {   // the traced layout in one step (build_blocks)
    run_dynbvh(s, [](const auto& t, const auto& ex) { return morton_wide::build_blocks(std::span<const Trianglef>(t), {}, ex); });
}
void BM_morton_wide8_then_blocks(benchmark::State& s) {   // the same tree in two steps: the index tree, then packed
    run_dynbvh(s, [](const auto& t, const auto& ex) { return make_wide_blocks(morton_wide::build<8>(std::span<const Trianglef>(t), {}, ex), t, ex); });
}
void BM_lbvh_wide8_blocks(benchmark::State& s) {
    run_dynbvh(s, [](const auto& t, const auto& ex) { return make_wide_blocks(lbvh::build_wide<8>(t, {.leaves = block_leaves}, ex), t, ex); });
}
void BM_ploc_r5_wide8_blocks(benchmark::State& s) {
    run_dynbvh(s, [](const auto& t, const auto& ex) { return make_wide_blocks(ploc::build_wide<8>(t, {.radius = 5, .leaves = block_leaves}, ex), t, ex); });
}
void BM_ploc_r5_blocks(benchmark::State& s) {   // the same tree in one step (ploc::build_blocks)
    run_dynbvh(s, [](const auto& t, const auto& ex) { return ploc::build_blocks(std::span<const Trianglef>(t), {.radius = 5, .leaves = block_leaves}, ex); });
}
void BM_ploc_r5_global_blocks(benchmark::State& s) {   // PLOC's original schedule (iterations over all clusters)
    run_dynbvh(s, [](const auto& t, const auto& ex) {
        return ploc::build_blocks(std::span<const Trianglef>(t), {.radius = 5, .subtree_clusters = 0, .leaves = block_leaves}, ex);
    });
}
void BM_kbvh_wide8_blocks(benchmark::State& s) {
    run_dynbvh(s, [](const auto& t, const auto& ex) {
        kbvh::Config<> c;
        c.builder.leaves = block_leaves;
        return make_wide_blocks(kbvh::build_wide<8>(t, c, ex), t, ex);
    });
}
void BM_kbvh_blocks(benchmark::State& s) {   // the same tree in one step (kbvh::build_blocks)
    run_dynbvh(s, [](const auto& t, const auto& ex) {
        kbvh::Config<> c;
        c.builder.leaves = block_leaves;
        return kbvh::build_blocks(std::span<const Trianglef>(t), c, ex);
    });
}

// Refit in place of an LBVH over the same frame (the work does not depend on how far vertices moved).
template <class Tree>
void run_refit(benchmark::State& state, Tree tree, const std::vector<Trianglef>& tris) {
    exec::default_executor ex{};
#if defined(_OPENMP)
    ex.threads = g_threads;
#endif
    const std::span<const Trianglef> t(tris);
    refit(tree, t, ex);   // warm-up
    for (auto _ : state) {
        refit(tree, t, ex);
        benchmark::DoNotOptimize(tree.nodes.data());
    }
    state.counters["tris"] = double(tris.size());
    state.counters["Mtris/s"] = benchmark::Counter(double(tris.size()) * double(state.iterations()) * 1e-6,
                                                   benchmark::Counter::kIsRate);
}
void BM_refit_binary(benchmark::State& s) {
    const auto& tris = scene_triangles(scene_of(s.range(0)));
    run_refit(s, lbvh::build(tris), tris);
}
void BM_refit_wide8(benchmark::State& s) {
    const auto& tris = scene_triangles(scene_of(s.range(0)));
    run_refit(s, lbvh::build_wide<8>(std::span<const Trianglef>(tris)), tris);
}
void BM_refit_wide8_blocks(benchmark::State& s) {   // the traced layout: blocks reloaded, boxes refitted
    const auto& tris = scene_triangles(scene_of(s.range(0)));
    run_refit(s, make_wide_blocks(morton_wide::build<8>(std::span<const Trianglef>(tris)), tris), tris);
}

void run_embree(benchmark::State& state, bench::EmbreeMode mode) {
    const auto& tris = scene_triangles(scene_of(state.range(0)));
    bench::EmbreeBvh e(g_threads, mode);
    e.update(tris);
    e.commit();   // warm-up, as for dynbvh
    for (auto _ : state) {
        state.PauseTiming();
        e.update(tris);   // a new frame's vertices: not part of the build
        state.ResumeTiming();
        e.commit();
    }
    state.counters["tris"] = double(tris.size());
    state.counters["Mtris/s"] = benchmark::Counter(double(tris.size()) * double(state.iterations()) * 1e-6,
                                                   benchmark::Counter::kIsRate);
}
void BM_embree_low(benchmark::State& s) { run_embree(s, bench::EmbreeMode::low); }
void BM_embree_medium(benchmark::State& s) { run_embree(s, bench::EmbreeMode::medium); }
void BM_embree_refit(benchmark::State& s) { run_embree(s, bench::EmbreeMode::refit); }

#define DYNBVH_SCENES ->Arg(0)->Arg(1)->Arg(2)->Unit(benchmark::kMillisecond)->UseRealTime()->MinTime(1.0)
BENCHMARK(BM_embree_low) DYNBVH_SCENES;
BENCHMARK(BM_lbvh) DYNBVH_SCENES;
BENCHMARK(BM_lbvh63) DYNBVH_SCENES;
BENCHMARK(BM_ploc_r5) DYNBVH_SCENES;
BENCHMARK(BM_ploc_r32) DYNBVH_SCENES;
BENCHMARK(BM_kbvh) DYNBVH_SCENES;
BENCHMARK(BM_binned_sah) DYNBVH_SCENES;
BENCHMARK(BM_lbvh_then_wide8) DYNBVH_SCENES;
BENCHMARK(BM_lbvh_wide8) DYNBVH_SCENES;
BENCHMARK(BM_ploc_r5_then_wide8) DYNBVH_SCENES;
BENCHMARK(BM_ploc_r5_wide8) DYNBVH_SCENES;
BENCHMARK(BM_kbvh_then_wide8) DYNBVH_SCENES;
BENCHMARK(BM_kbvh_wide8) DYNBVH_SCENES;
BENCHMARK(BM_binned_sah_then_wide8) DYNBVH_SCENES;
BENCHMARK(BM_binned_sah_wide8) DYNBVH_SCENES;
BENCHMARK(BM_morton_wide8) DYNBVH_SCENES;
BENCHMARK(BM_morton_wide8_blocks) DYNBVH_SCENES;
BENCHMARK(BM_morton_wide8_then_blocks) DYNBVH_SCENES;
BENCHMARK(BM_lbvh_wide8_blocks) DYNBVH_SCENES;
BENCHMARK(BM_ploc_r5_wide8_blocks) DYNBVH_SCENES;
BENCHMARK(BM_ploc_r5_blocks) DYNBVH_SCENES;
BENCHMARK(BM_ploc_r5_global_blocks) DYNBVH_SCENES;
BENCHMARK(BM_kbvh_wide8_blocks) DYNBVH_SCENES;
BENCHMARK(BM_kbvh_blocks) DYNBVH_SCENES;
BENCHMARK(BM_embree_medium) DYNBVH_SCENES;
BENCHMARK(BM_embree_refit) DYNBVH_SCENES;
BENCHMARK(BM_refit_binary) DYNBVH_SCENES;
BENCHMARK(BM_refit_wide8) DYNBVH_SCENES;
BENCHMARK(BM_refit_wide8_blocks) DYNBVH_SCENES;

} // namespace

int main(int argc, char** argv) {
    CLI::App app{"dynbvh-bench-build: build time of every dynbvh builder beside Embree 3 (LOW, MEDIUM, refit).", "dynbvh-bench-build"};
    cli::take_last(app);
    app.add_option("--threads", g_threads, "threads of every builder and of Embree (default 2, as in CI)")
        ->type_name("N")
        ->check(cli::number_in(1, 4096));
    if (const auto rc = cli::parse_with_benchmark_flags(app, argc, argv)) return *rc;
    benchmark::AddCustomContext("threads", std::to_string(g_threads));
    benchmark::Initialize(&argc, argv);
    if (benchmark::ReportUnrecognizedArguments(argc, argv)) return 1;
    benchmark::RunSpecifiedBenchmarks();
    benchmark::Shutdown();
    return 0;
}
