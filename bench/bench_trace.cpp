// Closest-hit trace speed of our binary and wide traversals next to Embree 3's rtcIntersect1 and its
// packets rtcIntersect8 / rtcIntersect16 (LOW and MEDIUM build quality), on the same frames, the same
// primary camera rays and the same thread counts in one run, so every figure reads as a ratio to
// Embree measured beside it (/low, /med: rtcIntersect1; /epkt: Embree's best packet figure).
//
//   dynbvh-bench-trace [--threads 1,2] [--res 854x480] [--reps 5] [--leaf 8] [--top 64]
//                      [--scenes cloth-ball,n-body,funnel,lattice,bunny,dragon] [--only METHOD]   (--x=v works too; --help)
//
// Scenes: the middle frame of the built-in cloth-ball, n-body and funnel (scene camera), `lattice`
// (scenes/lattice.hpp: 101k long thin triangles of beams crossing the scene, turned off the axes), and
// the Stanford bunny and dragon from DYNBVH_DATA_DIR when present (a camera that frames the mesh); on
// request (--scenes), the middle frame of BART's robots and kitchen from there, with their cameras.
// "mwide8 blk": morton_wide (the 8-wide tree straight from the sorted Morton codes) with block leaves.
// "hlbvh": LBVH whose top, above its subtrees of at most --top references, is rebuilt by binned SAH
// (lbvh::Config::sah_top, detail/sah_top.hpp; HLBVH, Pantaleoni and Luebke 2010).
// Packets: 4x2 pixels (8 rays) or 4x4 (16) inside each 16x16 tile, coherent context for Embree; ours
// ("... blk x8", "x16", "x32" = 8x4 pixels as two 4x4 halves: packet.hpp on the block trees, and on
// the default-leaf PLOC tree the study traces, "ploc wide8 x32"; trace::robust) beside them, checked to give the
// single-ray column's hits ray for ray ("packets!=single" must be 0).
// Trees: LBVH, PLOC (r = 5) and binned SAH, prim::indexed, each traced binary (traverse.hpp) and
// converted to 4-wide and 8-wide ("wide8") nodes (wide.hpp); trace::robust unless the row says "fast";
// "pre" = prim::copied. 8-wide nodes are tested with AVX when compiled with it (-march=native,
// DYNBVH_NATIVE), else in two SSE steps.
// Rays: one per pixel through the pixel centre, tiles of 16x16 pixels handed to OpenMP threads
// dynamically (Embree's device gets the same thread count). Each rep traces every method once
// (interleaved, so load from other processes hits all alike); the figure is the median over reps.
// Block-leaf trees (wide_blocks.hpp): "wide8 blk" = binary trees built with block_leaves (Ci 0.5,
// fuller leaves) converted to 8-wide nodes with leaves in SIMD blocks of 8 triangles; "w8 blk8 dfl" /
// "w8 blk4 dfl" = the default-leaf PLOC tree with blocks of 8 / 4 (the same hits as "ploc wide8").
// Also printed: SAH (Ct = 3, Ci = 2) of each tree (binary and wide), build and conversion time
// (median, at the largest thread count), and hit agreement with the binary traversal.
#include <algorithm>
#include <chrono>
#include <cstdio>
#include <functional>
#include <memory>
#include <string>
#include <vector>

#include <dynbvh/binned_sah.hpp>
#include <dynbvh/io/bart.hpp>
#include <dynbvh/io/obj.hpp>
#include <dynbvh/kbvh.hpp>
#include <dynbvh/io/ply.hpp>
#include <dynbvh/lbvh.hpp>
#include <dynbvh/packet.hpp>
#include <dynbvh/morton_wide.hpp>
#include <dynbvh/ploc.hpp>
#include <dynbvh/sah.hpp>
#include <scenes/builtin.hpp>
#include <scenes/lattice.hpp>
#include <dynbvh/traverse.hpp>
#include <dynbvh/wide.hpp>
#include <dynbvh/wide_blocks.hpp>

#include "cli.hpp"
#include "embree_bvh.hpp"
#include "camera.hpp"   // the study's RayGen (dynbvh_study)

namespace {

using namespace dynbvh;
using Clock = std::chrono::steady_clock;

double ms_since(Clock::time_point t0) { return std::chrono::duration<double, std::milli>(Clock::now() - t0).count(); }

double median(std::vector<double> v) {
    std::sort(v.begin(), v.end());
    const std::size_t n = v.size();
    return n == 0 ? 0 : (n % 2 ? v[n / 2] : 0.5 * (v[n / 2 - 1] + v[n / 2]));
}

struct SceneData {
    std::string name;
    std::vector<Trianglef> tris;
    io::Camera camera;
};

bool load_scene(const std::string& name, SceneData& out) {
    out.name = name;
    if (name == "lattice") {   // long thin crossing beams (scenes/lattice.hpp)
        io::Frame f = scenes::lattice();
        out.tris = std::move(f.triangles);
        out.camera = f.camera;
        return true;
    }
    if (name == "bunny" || name == "dragon") {
        const std::string path = std::string(DYNBVH_DATA_DIR) + (name == "bunny" ? "/meshes/bun_zipper.ply" : "/meshes/dragon_100k.obj");
        try {
            const io::Mesh mesh = name == "bunny" ? io::read_ply(path) : io::read_obj(path);
            out.tris = mesh.triangles();
            out.camera = io::frame_bounds_camera(mesh.bounds());
        } catch (const std::exception& e) {
            std::printf("(skipping %s: %s)\n", name.c_str(), e.what());
            return false;
        }
        return true;
    }
    if (name == "robots" || name == "kitchen") {   // BART (io/bart.hpp): the middle frame, its own camera
        const std::string path = std::string(DYNBVH_DATA_DIR) + (name == "robots" ? "/bart/robot/Robot.aff" : "/bart/kitchen/kitchen.aff");
        try {
            const auto bart = io::load_bart(path);
            io::Frame f;
            bart->frame(bart->frame_count() / 2, f);
            out.tris = std::move(f.triangles);
            out.camera = f.camera;
        } catch (const std::exception& e) {
            std::printf("(skipping %s: %s)\n", name.c_str(), e.what());
            return false;
        }
        return true;
    }
    auto scene = scenes::make_builtin(name);
    io::Frame f;
    scene->frame(scene->frame_count() / 2, f);
    out.tris = std::move(f.triangles);
    out.camera = f.camera;
    return true;
}

/// One traced method: a name and a function tracing every pixel into `out` with `threads` threads.
struct Method {
    std::string name;
    std::function<void(const study::RayGen&, int threads, std::vector<std::uint32_t>& out)> trace;
    std::vector<double> ms[2];   // per thread-count slot
};

/// Packets of N = 8 (4x2 pixels), 16 (4x4) or 32 (8x4) rays over each tile (study::for_each_packet, the study's
/// tiling): `isect(rays, valid, prims)` traces the packet's rays (valid[k] == 0 past the tile's edge)
/// and writes their hit prims.
template <int N, class Isect>
void trace_packets(const study::RayGen& gen, int threads, std::vector<std::uint32_t>& out, const Isect& isect) {
    const auto w = std::size_t(gen.width());
    exec::omp{.threads = threads}.for_tasks(gen.tile_count(), [&](std::size_t k) {
        study::for_each_packet<N>(gen, gen.tile(k), [&](const Rayf* rays, const int* valid, int x0, int y0) {
            std::uint32_t prims[N];
            isect(rays, valid, prims);
            for (int j = 0; j < N; ++j)
                if (valid[j]) out[std::size_t(y0 + study::packet_dy(j)) * w + std::size_t(x0 + study::packet_dx(j))] = prims[j];
        });
    });
}

template <class Isect>
void trace_image(const study::RayGen& gen, int threads, std::vector<std::uint32_t>& out, const Isect& isect) {
    const int w = gen.width();
    exec::omp{.threads = threads}.for_tasks(gen.tile_count(), [&](std::size_t k) {
        const study::Tile t = gen.tile(k);
        for (int y = t.y0; y < t.y1; ++y)
            for (int x = t.x0; x < t.x1; ++x) out[std::size_t(y) * std::size_t(w) + std::size_t(x)] = isect(gen.ray(x, y));
    });
}

} // namespace

int main(int argc, char** argv) {
    std::vector<int> thread_counts = {1, 2};
    int width = 854, height = 480, reps = 5;
    std::uint32_t max_leaf = LeafConfig{}.max_leaf_size;   // --leaf=N: most references per leaf of our trees
    std::vector<std::string> scene_names = {"cloth-ball", "n-body", "funnel", "lattice", "bunny", "dragon"};
    std::uint32_t top = 64;   // --top=N: lbvh::Config::sah_top of the "hlbvh" rows
    std::string only;   // --only=NAME: time just this method (and Embree LOW/MEDIUM), for profiling
    std::string res = "854x480";
    CLI::App app{"dynbvh-bench-trace: single-ray trace speed of our binary and wide traversals beside Embree's rtcIntersect1.",
                 "dynbvh-bench-trace"};
    cli::take_last(app);
    app.add_option("--threads", thread_counts, "one or two thread counts, comma separated (default 1,2)")
        ->type_name("N[,N]")
        ->delimiter(',')
        ->check(cli::number_in(1, 4096));
    app.add_option("--res", res, "image size (default 854x480)")->type_name("WxH");
    app.add_option("--reps", reps, "repetitions; the figure is the median (default 5)")->type_name("N")->check(cli::number_in(1, 10000));
    app.add_option("--leaf", max_leaf, "most references per leaf of our trees (default 8)")
        ->type_name("N")
        ->check(cli::number_in<std::uint32_t>(1, 256));
    app.add_option("--scenes", scene_names, "cloth-ball, n-body, funnel, lattice, bunny, dragon (default all), robots, kitchen (BART), comma separated")
        ->type_name("LIST")
        ->delimiter(',');
    app.add_option("--top", top, "sah_top of the hlbvh rows: subtrees of at most N references kept, the top by SAH (default 64)")
        ->type_name("N")
        ->check(cli::number_in<std::uint32_t>(1, 1u << 30));
    app.add_option("--only", only, "time just this method (and Embree LOW/MEDIUM), for profiling")->type_name("METHOD");
    app.footer("Options take their value as --x V or --x=V.");
    if (const auto rc = cli::parse(app, argc, argv)) return *rc;
    if (thread_counts.size() > 2) {
        std::fprintf(stderr, "dynbvh-bench-trace: --threads: at most two thread counts, not %zu (see --help)\n", thread_counts.size());
        return 2;
    }
    {
        char tail = 0;
        if (std::sscanf(res.c_str(), "%dx%d%c", &width, &height, &tail) != 2 || width < 1 || height < 1 || width > 16384 || height > 16384) {
            std::fprintf(stderr, "dynbvh-bench-trace: --res: '%s' is not WIDTHxHEIGHT (1 to 16384 each) (see --help)\n", res.c_str());
            return 2;
        }
    }
    for (const std::string& n : scene_names) {
        const auto builtin = scenes::builtin_names();
        if (n != "bunny" && n != "dragon" && n != "lattice" && n != "robots" && n != "kitchen" && std::find(builtin.begin(), builtin.end(), n) == builtin.end()) {
            std::fprintf(stderr, "dynbvh-bench-trace: --scenes: unknown scene '%s' (see --help)\n", n.c_str());
            return 2;
        }
    }
    const int build_threads = *std::max_element(thread_counts.begin(), thread_counts.end());
    const exec::omp bex{.threads = build_threads};
    std::printf("dynbvh-bench-trace: %dx%d primary rays, %d reps (median), max leaf %u, Embree %s, SIMD %s\n", width,
                height, reps, max_leaf, RTC_VERSION_STRING,
#if defined(DYNBVH_AVX512)
                "SSE, AVX for 8-wide nodes, AVX-512 for packets of 16"
#elif defined(DYNBVH_AVX)
                "SSE, AVX for 8-wide nodes"
#elif defined(DYNBVH_SSE)
                "SSE2"
#else
                "none (scalar)"
#endif
    );

    for (const std::string& sname : scene_names) {
        SceneData sc;
        if (!load_scene(sname, sc)) continue;
        const std::span<const Trianglef> tris(sc.tris);
        const study::RayGen gen(sc.camera, width, height);
        const std::size_t nrays = std::size_t(width) * std::size_t(height);

        // Build every tree once for tracing, and time LBVH build and wide conversion.
        const LeafConfig leaves{.max_leaf_size = max_leaf};
        auto lb = lbvh::build(tris, {.leaves = leaves}, bex);
        auto pl = ploc::build(tris, {.radius = 5, .leaves = leaves}, bex);
        auto sb = binned_sah::build(tris, {.leaves = leaves}, bex);
        auto plp = ploc::build<Node<>, prim::copied>(tris, {.radius = 5, .leaves = leaves}, bex);
        std::vector<double> t_lbvh, t_conv, t_conv_ploc, t_lbvh1, t_conv1, t_conv8, t_conv8b;
        for (int r = 0; r < std::max(reps, 5); ++r) {
            auto t0 = Clock::now();
            auto b = lbvh::build(tris, {.leaves = leaves}, bex);
            t_lbvh.push_back(ms_since(t0));
            t0 = Clock::now();
            auto w = make_wide(b, bex);
            t_conv.push_back(ms_since(t0));
            t0 = Clock::now();
            auto w8 = make_wide<8>(b, bex);
            t_conv8.push_back(ms_since(t0));
            t0 = Clock::now();
            auto w8b = make_wide_blocks<8>(b, tris, bex);
            t_conv8b.push_back(ms_since(t0));
            t0 = Clock::now();
            auto w2 = make_wide(pl, bex);
            t_conv_ploc.push_back(ms_since(t0));
            t0 = Clock::now();
            auto b1 = lbvh::build(tris, {.leaves = leaves}, exec::serial{});
            t_lbvh1.push_back(ms_since(t0));
            t0 = Clock::now();
            auto w1 = make_wide(b1, exec::serial{});
            t_conv1.push_back(ms_since(t0));
        }
        const auto lw = make_wide(lb, bex), pw = make_wide(pl, bex), sw = make_wide(sb, bex);
        const auto pwp = make_wide(plp, bex);
        const auto lw8 = make_wide<8>(lb, bex), pw8 = make_wide<8>(pl, bex), sw8 = make_wide<8>(sb, bex);
        // block trees: binary trees built with block_leaves (wide_blocks.hpp) in blocks of 8, and the
        // default-leaf PLOC tree in blocks of 8 and 4 ("dfl")
        LeafConfig bleaves = block_leaves;
        bleaves.max_leaf_size = std::max<std::uint32_t>(max_leaf, 1);
        const auto lbk = make_wide_blocks<8>(lbvh::build(tris, {.leaves = bleaves}, bex), tris, bex);
        const auto hbk = make_wide_blocks<8>(lbvh::build(tris, {.leaves = bleaves, .sah_top = top}, bex), tris, bex);   // HLBVH
        const auto pbk = make_wide_blocks<8>(ploc::build(tris, {.radius = 5, .leaves = bleaves}, bex), tris, bex);
        const auto sbk = make_wide_blocks<8>(binned_sah::build(tris, {.leaves = bleaves}, bex), tris, bex);
        kbvh::Config<> kcfg;   // presplit (default budget) + PLOC r = 5
        kcfg.builder.leaves = bleaves;
        const auto kbk = make_wide_blocks<8>(kbvh::build(tris, kcfg, bex), tris, bex);
        const auto mwk = make_wide_blocks(morton_wide::build<8>(tris, {}, bex), tris, bex);   // morton_wide.hpp
        const auto pw8b8 = make_wide_blocks<8, 8>(pl, tris, bex);
        const auto pw8b4 = make_wide_blocks<8, 4>(pl, tris, bex);

        bench::EmbreeBvh elow(build_threads, bench::EmbreeMode::low), emed(build_threads, bench::EmbreeMode::medium);
        elow.update(tris);
        elow.commit();
        emed.update(tris);
        emed.commit();

        std::vector<Method> methods;
        auto add = [&](std::string name, auto isect) {
            methods.push_back({std::move(name), [isect](const study::RayGen& g, int th, std::vector<std::uint32_t>& out) {
                                   trace_image(g, th, out, isect);
                               }, {}});
        };
        add("embree-low", [&](const Rayf& r) { return elow.intersect(r).prim; });
        add("embree-medium", [&](const Rayf& r) { return emed.intersect(r).prim; });
        // Embree's packets (rtcIntersect8 on 4x2 pixels, rtcIntersect16 on 4x4, coherent context)
        auto add_packets = [&](std::string name, auto isect, auto n) {
            methods.push_back({std::move(name), [isect](const study::RayGen& g, int th, std::vector<std::uint32_t>& out) {
                                   trace_packets<decltype(n)::value>(g, th, out, isect);
                               }, {}});
        };
        auto embree_packets = [&](const bench::EmbreeBvh& eb, auto n) {
            return [&eb](const Rayf* rays, const int* valid, std::uint32_t* prims) {
                constexpr int N = decltype(n)::value;
                Hitf h[N];
                eb.intersect_packet<N>(rays, valid, h);
                for (int k = 0; k < N; ++k) prims[k] = h[k].prim;
            };
        };
        using P8 = std::integral_constant<int, 8>;
        using P16 = std::integral_constant<int, 16>;
        using P32 = std::integral_constant<int, 32>;
        add_packets("embree-low x8", embree_packets(elow, P8{}), P8{});
        add_packets("embree-low x16", embree_packets(elow, P16{}), P16{});
        add_packets("embree-medium x8", embree_packets(emed, P8{}), P8{});
        add_packets("embree-medium x16", embree_packets(emed, P16{}), P16{});
        const std::size_t embree_end = methods.size();   // methods[2 .. embree_end): Embree's packets
        // Our packets (packet.hpp) on the block trees, the same tiles: the same hits as the single rays
        auto our_packets = [&](const auto& tree, auto n) {
            return [&tree, tris](const Rayf* rays, const int* valid, std::uint32_t* prims) {
                constexpr int N = decltype(n)::value;
                RayPacket<float, N> p;
                std::uint32_t active = 0;
                for (int k = 0; k < N; ++k) {
                    p.set(k, rays[k]);
                    active |= valid[k] ? std::uint32_t(1) << k : 0u;
                }
                const HitPacket<float, N> h = intersect(tree, tris, p, active);
                for (int k = 0; k < N; ++k) prims[k] = h.prim[k];
            };
        };
        const std::size_t first_our_packets = methods.size();
        add_packets("lbvh wide8 blk x16", our_packets(lbk, P16{}), P16{});
        add_packets("lbvh wide8 blk x32", our_packets(lbk, P32{}), P32{});
        add_packets("hlbvh wide8 blk x32", our_packets(hbk, P32{}), P32{});
        add_packets("ploc wide8 blk x8", our_packets(pbk, P8{}), P8{});
        add_packets("ploc wide8 blk x16", our_packets(pbk, P16{}), P16{});
        add_packets("sah wide8 blk x8", our_packets(sbk, P8{}), P8{});
        add_packets("sah wide8 blk x16", our_packets(sbk, P16{}), P16{});
        add_packets("sah wide8 blk x32", our_packets(sbk, P32{}), P32{});
        add_packets("ploc wide8 blk x32", our_packets(pbk, P32{}), P32{});
        add_packets("ploc wide8 x32", our_packets(pw8, P32{}), P32{});
        add_packets("kbvh wide8 blk x16", our_packets(kbk, P16{}), P16{});
        add_packets("mwide8 blk x16", our_packets(mwk, P16{}), P16{});
        const std::size_t first_ours = methods.size();   // methods[0], [1]: Embree LOW / MEDIUM rtcIntersect1
        add("lbvh binary", [&](const Rayf& r) { return intersect(lb, tris, r).prim; });
        add("lbvh wide", [&](const Rayf& r) { return intersect(lw, tris, r).prim; });
        add("ploc binary", [&](const Rayf& r) { return intersect(pl, tris, r).prim; });
        add("ploc wide", [&](const Rayf& r) { return intersect(pw, tris, r).prim; });
        add("sah binary", [&](const Rayf& r) { return intersect(sb, tris, r).prim; });
        add("sah wide", [&](const Rayf& r) { return intersect(sw, tris, r).prim; });
        add("ploc wide pre", [&](const Rayf& r) { return intersect(pwp, tris, r).prim; });
        add("ploc binary fast", [&](const Rayf& r) { return intersect<trace::fast>(pl, tris, r).prim; });
        add("ploc wide fast", [&](const Rayf& r) { return intersect<trace::fast>(pw, tris, r).prim; });
        const std::size_t first_wide8 = methods.size();
        add("lbvh wide8", [&](const Rayf& r) { return intersect(lw8, tris, r).prim; });
        add("ploc wide8", [&](const Rayf& r) { return intersect(pw8, tris, r).prim; });
        add("sah wide8", [&](const Rayf& r) { return intersect(sw8, tris, r).prim; });
        add("ploc wide8 fast", [&](const Rayf& r) { return intersect<trace::fast>(pw8, tris, r).prim; });
        // 8-wide nodes with SIMD triangle-block leaves (wide_blocks.hpp)
        add("lbvh wide8 blk", [&](const Rayf& r) { return intersect(lbk, tris, r).prim; });
        add("hlbvh wide8 blk", [&](const Rayf& r) { return intersect(hbk, tris, r).prim; });
        add("ploc wide8 blk", [&](const Rayf& r) { return intersect(pbk, tris, r).prim; });
        add("sah wide8 blk", [&](const Rayf& r) { return intersect(sbk, tris, r).prim; });
        add("kbvh wide8 blk", [&](const Rayf& r) { return intersect(kbk, tris, r).prim; });
        add("mwide8 blk", [&](const Rayf& r) { return intersect(mwk, tris, r).prim; });
        add("mwide8 blk fast", [&](const Rayf& r) { return intersect<trace::fast>(mwk, tris, r).prim; });
        add("ploc wide8 blk fast", [&](const Rayf& r) { return intersect<trace::fast>(pbk, tris, r).prim; });
        add("sah wide8 blk fast", [&](const Rayf& r) { return intersect<trace::fast>(sbk, tris, r).prim; });
        // where the robust policy's cost goes: its triangle test with the fast box test, and the other way round
        add("ploc wide8 blk wt+fbox", [&](const Rayf& r) { return intersect<trace::policy<box::fast, tri::watertight>>(pbk, tris, r).prim; });
        add("ploc wide8 blk mt+rbox", [&](const Rayf& r) { return intersect<trace::policy<box::robust, tri::moller_trumbore>>(pbk, tris, r).prim; });
        add("ploc w8 blk8 dfl", [&](const Rayf& r) { return intersect(pw8b8, tris, r).prim; });
        add("ploc w8 blk4 dfl", [&](const Rayf& r) { return intersect(pw8b4, tris, r).prim; });
        add("ploc w8 blk4 dfl fast", [&](const Rayf& r) { return intersect<trace::fast>(pw8b4, tris, r).prim; });

        // Agreement: wide vs binary on the same tree (robust: must be identical up to exact ties).
        std::vector<std::uint32_t> a(nrays), b(nrays), e(nrays);
        std::size_t hits = 0;
        std::string agree;
        for (std::size_t m = first_ours; m + 1 < first_ours + 6; m += 2) {
            methods[m].trace(gen, build_threads, a);
            methods[m + 1].trace(gen, build_threads, b);
            std::size_t diff = 0;
            for (std::size_t i = 0; i < nrays; ++i) diff += a[i] != b[i];
            agree += " " + methods[m].name.substr(0, methods[m].name.find(' ')) + ":" + std::to_string(diff);
            // the 8-wide tree of the same binary tree
            methods[first_wide8 + (m - first_ours) / 2].trace(gen, build_threads, b);
            diff = 0;
            for (std::size_t i = 0; i < nrays; ++i) diff += a[i] != b[i];
            agree += "/" + std::to_string(diff);
        }
        // the block-leaf trees of the same PLOC tree: the same hits as its 8-wide tree
        for (const char* pair : {"ploc w8 blk8 dfl", "ploc w8 blk4 dfl"}) {
            const auto it = std::find_if(methods.begin(), methods.end(), [&](const Method& m) { return m.name == pair; });
            const auto w8it = std::find_if(methods.begin(), methods.end(), [&](const Method& m) { return m.name == "ploc wide8"; });
            it->trace(gen, build_threads, a);
            w8it->trace(gen, build_threads, b);
            std::size_t diff = 0;
            for (std::size_t i = 0; i < nrays; ++i) diff += a[i] != b[i];
            agree += std::string(" ") + pair + ":" + std::to_string(diff);
        }
        methods[first_ours].trace(gen, build_threads, a);   // lbvh binary, for the hit count below
        methods[0].trace(gen, build_threads, e);
        std::size_t emb_diff = 0;
        for (std::size_t i = 0; i < nrays; ++i) {
            hits += a[i] != invalid_prim;
            emb_diff += (a[i] != invalid_prim) != (e[i] != invalid_prim);
        }
        // our packets against our single rays on the same tree (prims: must be identical)
        {
            std::size_t diff = 0;
            for (std::size_t m = first_our_packets; m < first_ours; ++m) {
                const std::string single = methods[m].name.substr(0, methods[m].name.rfind(' '));
                const auto it = std::find_if(methods.begin(), methods.end(), [&](const Method& x) { return x.name == single; });
                methods[m].trace(gen, build_threads, a);
                it->trace(gen, build_threads, b);
                for (std::size_t i = 0; i < nrays; ++i) diff += a[i] != b[i];
            }
            agree += " packets!=single:" + std::to_string(diff);
        }
        // Embree's packets against its single rays on the same scene (hit/miss)
        std::size_t pkt_diff = 0;
        for (std::size_t m = 2; m < embree_end; ++m) {
            methods[m].trace(gen, build_threads, b);
            for (std::size_t i = 0; i < nrays; ++i) pkt_diff += (b[i] != invalid_prim) != (e[i] != invalid_prim);
        }

        for (int r = 0; r < reps; ++r)
            for (std::size_t ti = 0; ti < thread_counts.size(); ++ti)
                for (auto& m : methods) {
                    if (!only.empty() && m.name != only && m.name.rfind("embree", 0) != 0) continue;   // Embree always runs
                    const auto t0 = Clock::now();
                    m.trace(gen, thread_counts[ti], a);
                    m.ms[ti].push_back(ms_since(t0));
                }

        std::printf("\n== %s: %zu triangles, %zu rays, %.1f%% hit; wide!=binary rays (4-wide/8-wide; block trees != 8-wide):%s; hit/miss differs from embree-low on %zu rays (embree packets: %zu)\n",
                    sname.c_str(), tris.size(), nrays, 100.0 * double(hits) / double(nrays), agree.c_str(), emb_diff, pkt_diff);
        const SahCost sc3{.ct = 3, .ci = 2};
        std::printf("   SAH binary/wide: lbvh %.2f/%.2f  ploc %.2f/%.2f  sah %.2f/%.2f;  wide nodes (depth) lbvh %zu (%u) ploc %zu (%u) sah %zu (%u)\n",
                    sah_cost(lb, sc3), sah_cost(lw, sc3), sah_cost(pl, sc3), sah_cost(pw, sc3), sah_cost(sb, sc3),
                    sah_cost(sw, sc3), lw.nodes.size(), lw.depth, pw.nodes.size(), pw.depth, sw.nodes.size(), sw.depth);
        std::printf("   SAH 8-wide: lbvh %.2f  ploc %.2f  sah %.2f;  8-wide nodes (depth) lbvh %zu (%u) ploc %zu (%u) sah %zu (%u); "
                    "8-wide conversion of lbvh %.3f ms, with 8-lane block leaves %.3f ms\n",
                    sah_cost(lw8, sc3), sah_cost(pw8, sc3), sah_cost(sw8, sc3), lw8.nodes.size(), lw8.depth, pw8.nodes.size(),
                    pw8.depth, sw8.nodes.size(), sw8.depth, median(t_conv8), median(t_conv8b));
        std::printf("   SAH 8-wide blocks: lbvh %.2f  hlbvh (top %u) %.2f  ploc %.2f  sah %.2f  kbvh %.2f  mwide %.2f\n", sah_cost(lbk, sc3), top,
                    sah_cost(hbk, sc3), sah_cost(pbk, sc3), sah_cost(sbk, sc3), sah_cost(kbk, sc3), sah_cost(mwk, sc3));
        const double ml = median(t_lbvh), mc = median(t_conv), mcp = median(t_conv_ploc);
        const double ml1 = median(t_lbvh1), mc1 = median(t_conv1);
        std::printf("   build (%d threads): lbvh %.2f ms, wide conversion %.3f ms (%.1f%% of lbvh), of ploc tree %.3f ms;"
                    " serial: lbvh %.2f ms, conversion %.3f ms (%.1f%%)\n",
                    build_threads, ml, mc, 100.0 * mc / ml, mcp, ml1, mc1, 100.0 * mc1 / ml1);
        std::printf("   %-22s", "method");
        for (int th : thread_counts) std::printf(" | %2d thr: Mrays/s  /low  /med /epkt", th);
        std::printf("\n");
        for (const auto& m : methods) {
            if (m.ms[0].empty()) continue;
            std::printf("   %-22s", m.name.c_str());
            for (std::size_t ti = 0; ti < thread_counts.size(); ++ti) {
                const double mr = double(nrays) / median(m.ms[ti]) * 1e-3;
                const double lo = double(nrays) / median(methods[0].ms[ti]) * 1e-3;
                const double me = double(nrays) / median(methods[1].ms[ti]) * 1e-3;
                double pk = 0;   // Embree's best packet figure (LOW/MEDIUM x 8/16)
                for (std::size_t p = 2; p < embree_end; ++p)
                    if (!methods[p].ms[ti].empty()) pk = std::max(pk, double(nrays) / median(methods[p].ms[ti]) * 1e-3);
                std::printf(" |         %7.2f %5.2f %5.2f %5.2f", mr, mr / lo, mr / me, pk > 0 ? mr / pk : 0.0);
            }
            std::printf("\n");
        }
        std::fflush(stdout);
    }
    return 0;
}
