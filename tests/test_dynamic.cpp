// dynamic.hpp: the refit-or-rebuild policy decides exactly as its rule says (expected decisions
// recomputed here from refitted copies), rebuilds on topology and finiteness changes, and its tree
// always traces like brute force; the asynchronous mode serves exact results every frame and swaps.
#include "support.hpp"
#include "hit_compare.hpp"

#include <algorithm>
#include <cmath>
#include <cstring>
#include <limits>
#include <string>
#include <vector>

#include <dynbvh/dynamic.hpp>
#include <dynbvh/refit.hpp>
#include <dynbvh/sah.hpp>
#include <dynbvh/wide_blocks.hpp>

using namespace dynbvh;
using namespace dynbvh::test;

namespace {

/// Frame f of the scripted animation: every triangle drifts along its own fixed random direction,
/// further each frame, so the refitted boxes grow and overlap more and more (the SAH, which is
/// relative to the root's area, grows; a uniform explosion would leave it unchanged).
std::vector<Trianglef> exploding(const std::vector<Trianglef>& base, int f) {
    std::vector<Trianglef> out = base;
    for (std::size_t i = 0; i < out.size(); ++i) {
        Rng r(1000 + i);
        const Vec3f v{r.uniform(-1, 1), r.uniform(-1, 1), r.uniform(-1, 1)};
        const Vec3f d = v * (0.04f * float(f));
        out[i].p0 += d;
        out[i].p1 += d;
        out[i].p2 += d;
    }
    return out;
}

/// Frame f of a scene that rearranges itself every frame: every triangle jumps by its own random
/// offset, new each frame, as large as the scene (a refitted tree is always far worse than a fresh one).
std::vector<Trianglef> scrambled(const std::vector<Trianglef>& base, int f) {
    std::vector<Trianglef> out = base;
    for (std::size_t i = 0; i < out.size(); ++i) {
        Rng r(7919 * std::uint64_t(f) + i);
        const Vec3f d{r.uniform(-2, 2), r.uniform(-2, 2), r.uniform(-2, 2)};
        out[i].p0 += d;
        out[i].p1 += d;
        out[i].p2 += d;
    }
    return out;
}

/// Rays from around the scene at points on random triangles (most hit), random directions (most
/// miss), plus a miss and a NaN ray.
std::vector<Rayf> probe_rays(const std::vector<Trianglef>& tris, std::size_t n, std::uint64_t seed) {
    std::vector<Rayf> rays;
    const float nan = std::numeric_limits<float>::quiet_NaN();
    rays.push_back({{nan, 0, 0}, {0, 0, 1}});
    if (tris.empty()) return rays;
    AABBf b;
    for (const auto& t : tris) b.extend(t.bounds());
    Rng r(seed);
    const Vec3f c = b.center(), e = b.diagonal();
    for (std::size_t i = 0; i < n; ++i) {
        const Trianglef& t = tris[r.next() % tris.size()];
        const float u = r.uniform(), v = r.uniform() * (1 - u);
        const Vec3f target = t.p0 + (t.p1 - t.p0) * u + (t.p2 - t.p0) * v;
        const Vec3f org = c + Vec3f{r.uniform(-1, 1), r.uniform(-1, 1), r.uniform(-1, 1)} * (2 * length(e) + 1);
        rays.push_back({org, i % 4 == 3 ? Vec3f{r.uniform(-1, 1), r.uniform(-1, 1), r.uniform(-1, 1)} : target - org});
    }
    rays.push_back({c + Vec3f{0, 0, 100 * (length(e) + 1)}, {0, 0, 1}});   // away from everything
    return rays;
}

template <class Tree>
void check_exact(const Tree& bvh, const std::vector<Trianglef>& tris, std::uint64_t seed, const std::string& what) {
    const std::span<const Trianglef> s(tris);
    std::size_t bad = 0, hits = 0;
    for (const Rayf& ray : probe_rays(tris, sanitizer_scaled(200), seed)) {
        const Hitf h = intersect(bvh, s, ray);
        const Hitf e = brute_force_intersect(s, ray);
        hits += bool(e);
        if (!same_hit<tri::watertight>(h, e, s, ray)) {
            if (++bad <= 3) MESSAGE(what, ": ", describe(ray, h, e));
        }
        if (occluded(bvh, s, ray) != brute_force_occluded(s, ray)) ++bad;
    }
    CHECK_MESSAGE(bad == 0, what, ": ", bad, " rays differ from brute force");
    CHECK(hits > 0);
}

/// The rebuild-streak rule as dynamic.hpp's file comment states it, kept by the test: after two frames
/// in a row that rebuilt at the first refit after a rebuild by a clear margin, frames rebuild without
/// refitting, except every probe-th frame of the run, which refits and applies the rule.
struct StreakModel {
    unsigned probe = 8;
    unsigned streak = 0, probes = 0;
    bool fresh = true;   // the tree was built at the previous frame
    /// Whether this frame rebuilds without a refit (then counted).
    bool direct() {
        if (!(probe > 1 && streak >= 2 && probes + 1 < probe)) return false;
        ++probes;
        return true;
    }
    /// A refitted frame whose rule said `rebuild`, `clear` when by the margin.
    void refitted(bool rebuild, bool clear) {
        probes = 0;
        streak = rebuild && clear && fresh ? streak + 1 : 0;
    }
    /// At the end of a frame: whether it rebuilt.
    void end(bool rebuilt) { fresh = rebuilt; }
};

/// Applies the expected decision `want` to the test's own tree `mine` (a PLOC rebuild, or nothing: it
/// was refitted already) and checks the policy's report against it; `why` = the reason of a rebuild
/// after frame 0.
/// `refitted`: refit_sah's SAH of `mine` this frame (what a refit frame reports).
void expect_decision(const FrameReport& r, Decision want, Reason why, int f, std::span<const Trianglef> s, Bvh<>& mine,
                     double& rebuilt_sah, int& rebuilds, int& refits, double refitted) {
    const exec::serial ex;
    if (want == Decision::rebuild) {
        mine = ploc::build<Node<>, prim::indexed>(s, {}, ex);
        rebuilt_sah = sah_cost(mine, {}, ex);
        ++rebuilds;
        if (f > 0) CHECK(r.reason == why);
        CHECK(same_bits(r.sah_after, rebuilt_sah));
    } else {
        ++refits;
        CHECK(r.reason == Reason::none);
        CHECK(same_bits(r.sah_after, refitted));
    }
    CHECK(r.decision == want);
    CHECK(same_bits(r.sah_rebuilt, rebuilt_sah));
}

/// Whether two block trees are the same, bit for bit: every node (boxes, children, counts) and every
/// block's vertices, triangle indices and lane count (not the blocks' padding bytes).
template <class Tree>
bool same_block_tree(const Tree& a, const Tree& b) {
    if (a.nodes.size() != b.nodes.size() || a.blocks.size() != b.blocks.size() || a.depth != b.depth) return false;
    if (std::memcmp(a.nodes.data(), b.nodes.data(), a.nodes.size() * sizeof(a.nodes[0])) != 0) return false;
    for (std::size_t i = 0; i < a.blocks.size(); ++i) {
        const auto &x = a.blocks[i], &y = b.blocks[i];
        if (x.count != y.count || std::memcmp(x.v, y.v, sizeof x.v) != 0 || std::memcmp(x.prim, y.prim, sizeof x.prim) != 0) return false;
    }
    return true;
}

} // namespace

TEST_CASE("Dynamic: rebuilds exactly when the refitted SAH exceeds the threshold times the last rebuild's") {
    const auto base = sphere(12, 24);
    const exec::serial ex;
    const DynamicConfig<ploc::Config> cfg{.rebuild_threshold = 1.3};
    Dynamic<builder::ploc, Node<>, prim::indexed, exec::serial> dyn(cfg, ex);
    // The expectation, computed independently: a tree of our own, refitted each frame, rebuilt by the rule.
    Bvh<> mine;
    double rebuilt_sah = 0;
    int rebuilds = 0, refits = 0, streaks = 0;
    StreakModel streak;
    for (int f = 0; f < 24; ++f) {
        // from frame 16 on the scene rearranges itself every frame: the rule rebuilds every frame (a streak)
        const auto tris = f < 16 ? exploding(base, f) : scrambled(base, f);
        const std::span<const Trianglef> s(tris);
        const FrameReport r = dyn.update(s);
        CAPTURE(f);
        CHECK(r.frame == std::size_t(f));
        Decision want = Decision::refit;
        Reason why = Reason::sah_growth;
        double before = std::numeric_limits<double>::quiet_NaN();
        if (f == 0) {
            want = Decision::rebuild;
            CHECK(r.reason == Reason::first_frame);
        } else if (streak.direct()) {
            want = Decision::rebuild;
            why = Reason::streak;
            ++streaks;
        } else {
            before = refit_sah(mine, s, {}, ex).sah;
            if (before > 1.3 * rebuilt_sah) want = Decision::rebuild;
            streak.refitted(want == Decision::rebuild, before >= 2 * 1.3 * rebuilt_sah);
        }
        CHECK(same_bits(r.sah_before, before));
        streak.end(want == Decision::rebuild);
        expect_decision(r, want, why, f, s, mine, rebuilt_sah, rebuilds, refits, before);
        CHECK(dyn.bvh().nodes.size() == mine.nodes.size());
        CHECK(r.ms >= 0);
        CHECK(structure_problems(dyn.bvh(), tris) == "");
        check_exact(dyn.bvh(), tris, 100 + std::uint64_t(f), "frame " + std::to_string(f));
    }
    // The script must exercise both branches of the rule, and a streak.
    CHECK(rebuilds >= 3);
    CHECK(refits >= 3);
    CHECK(streaks >= 3);
}

TEST_CASE("Dynamic over the traced layout: the block tree itself rebuilt and refitted in place, judged by its own SAH") {
    using Tree = WideBvh<WideNode<float, std::uint32_t, 8>, prim::blocks<8>>;
    const auto base = sphere(12, 24);
    const exec::serial ex;
    const DynamicConfig<ploc::Config> cfg{.rule = RebuildRule::sah_growth, .rebuild_threshold = 1.3, .probe_every = 0};
    Dynamic<builder::ploc, WideNode<float, std::uint32_t, 8>, prim::blocks<8>, exec::serial> dyn(cfg, ex), from_mesh(cfg, ex);
    static_assert(std::is_same_v<decltype(dyn)::bvh_type, Tree>);
    // The expectation, computed independently: a block tree of our own, refitted in place each frame,
    // rebuilt by the rule on its wide SAH.
    Tree mine;
    double rebuilt_sah = 0;
    int rebuilds = 0, refits = 0;
    const auto same_tree = [](const Tree& a, const Tree& b) { return same_block_tree(a, b); };
    for (int f = 0; f < 24; ++f) {
        const auto tris = f < 16 ? exploding(base, f) : scrambled(base, f);
        const std::span<const Trianglef> s(tris);
        // the same frame as an indexed mesh read in place: three vertices per triangle
        std::vector<Vec3f> vertices;
        std::vector<std::uint32_t> indices;
        for (const Trianglef& t : tris) {
            for (const Vec3f& p : {t.p0, t.p1, t.p2}) {
                indices.push_back(std::uint32_t(vertices.size()));
                vertices.push_back(p);
            }
        }
        const FrameReport r = dyn.update(s);
        const FrameReport rm = from_mesh.update(MeshView<float>(vertices, indices));
        CAPTURE(f);
        Decision want = Decision::rebuild;
        double before = std::numeric_limits<double>::quiet_NaN();
        if (f > 0) {
            const RefitReport rep = refit_sah(mine, s, {}, ex);
            CHECK(same_bits(rep.sah, sah_cost(mine, {}, ex)));   // the wide SAH, bit for bit
            CHECK(rep.nonfinite == 0);
            before = rep.sah;
            want = before > 1.3 * rebuilt_sah ? Decision::rebuild : Decision::refit;
        }
        if (want == Decision::rebuild) {
            mine = ploc::build_blocks<8, 8>(s, {}, ex);
            rebuilt_sah = sah_cost(mine, {}, ex);
            ++rebuilds;
        } else {
            ++refits;
        }
        CHECK(r.decision == want);
        CHECK(r.reason == (f == 0 ? Reason::first_frame : want == Decision::rebuild ? Reason::sah_growth : Reason::none));
        CHECK(same_bits(r.sah_before, before));
        CHECK(same_bits(r.sah_after, want == Decision::rebuild ? rebuilt_sah : before));
        CHECK(same_bits(r.sah_rebuilt, rebuilt_sah));
        CHECK(same_tree(dyn.bvh(), mine));                // bit for bit: nodes and blocks
        CHECK(rm.decision == r.decision);
        CHECK(same_tree(from_mesh.bvh(), mine));          // the mesh view gives the span's trees
        check_exact(dyn.bvh(), tris, 300 + std::uint64_t(f), "block tree, frame " + std::to_string(f));
    }
    CHECK(rebuilds >= 3);
    CHECK(refits >= 3);
    // A triangle turning non-finite is counted by the in-place refit and rebuilds the tree without it.
    auto tris = exploding(base, 3);
    tris[5].p1.x = std::numeric_limits<float>::quiet_NaN();
    Tree copy = mine;   // the in-place refit counts it: one triangle
    CHECK(refit_sah(copy, std::span<const Trianglef>(tris), {}, ex).nonfinite == 1);
    const FrameReport r = dyn.update(std::span<const Trianglef>(tris));
    CHECK(r.decision == Decision::rebuild);
    CHECK(r.reason == Reason::finiteness);
    CHECK(dyn.bvh().primitive_count == tris.size());
    check_exact(dyn.bvh(), tris, 999, "block tree, a NaN vertex");
    // The lbvh and binned-SAH policies build the same traced layout as their conversion gives.
    Dynamic<builder::lbvh, WideNode<float, std::uint32_t, 4>, prim::blocks<4>, exec::serial> lb({}, ex);
    const auto frame = exploding(base, 1);
    lb.update(std::span<const Trianglef>(frame));
    const auto want4 = make_wide_blocks<4, 4>(lbvh::build(std::span<const Trianglef>(frame), {}, ex), std::span<const Trianglef>(frame), ex);
    CHECK(same_block_tree(lb.bvh(), want4));
    check_exact(lb.bvh(), frame, 1001, "lbvh block tree");
}

TEST_CASE("Dynamic: the amortized rule rebuilds exactly when the estimated trace time lost reaches the rebuild cost") {
    const auto base = sphere(12, 24);
    const exec::serial ex;
    constexpr double cost = 5.0;   // what a rebuild is taken to cost (ms): fixed, so the script is exact
    // The default initial elasticity (1/3) and 1 (trace time proportional to the SAH).
    for (const double e0 : {DynamicConfig<ploc::Config>{}.initial_elasticity, 1.0}) {
        CAPTURE(e0);
        Dynamic<builder::ploc, Node<>, prim::indexed, exec::serial> dyn({.rule = RebuildRule::amortized, .rebuild_ms = cost, .initial_elasticity = e0}, ex);
        // Scripted trace times (ms) per frame, and the expectation recomputed independently: our own tree,
        // refitted each frame; with scaled(T, a, b) = T (b / a)^e, loss = trust * (sum over traced frames of
        // T - scaled(T, s, s_rebuilt), plus this frame's prediction for T' = scaled(T_prev, s_prev, s)); after
        // each rebuild the first trace time moves trust halfway to the measured share of the predicted saving
        // (clamped to [0, 1], >= 1/8); e (1 at first) is log(T / T1) / log(s / s1) against the first frame
        // traced since the last rebuild once s >= 1.2 s1, clamped to [1/8, 1]; e0 before that.
        const double trace_ms[] = {10, 12, 9, 11.5, 30, 4, 4, 50, 1, 1, 1, 20, 20, 20, 20, 20, 20, 20, 20, 20, 20, 20, 20, 20};
        Bvh<> mine;
        double rebuilt_sah = 0, loss = 0, prev_ms = 0, prev_sah = 0, trust = 1, check_refit = 0, check_fresh = 0;
        double e = e0, first_ms = 0, first_sah = 0;
        bool check = false, first_pending = false;
        int measured_e = 0, clamped_e = 0;
        const auto scaled = [&](double ms, double a, double b) { return e == 1.0 ? ms * b / a : ms * std::pow(b / a, e); };
        int rebuilds = 0, refits = 0, checks = 0, streaks = 0;
        StreakModel streak;
        for (int f = 0; f < 24; ++f) {
            // from frame 18 on the scene rearranges itself every frame: a streak of rebuilds
            const auto tris = f < 18 ? exploding(base, f) : scrambled(base, f);
            const std::span<const Trianglef> s(tris);
            const FrameReport r = dyn.update(s);
            CAPTURE(f);
            Decision want = Decision::refit;
            Reason why = Reason::amortized;
            double now = std::numeric_limits<double>::quiet_NaN();   // the serving tree's SAH this frame
            if (f == 0) {
                want = Decision::rebuild;
                CHECK(r.reason == Reason::first_frame);
            } else if (streak.direct()) {
                want = Decision::rebuild;
                why = Reason::streak;
                ++streaks;
                CHECK(r.loss_ms == 0);
                CHECK(r.rebuild_cost_ms == cost);
                CHECK(std::isnan(r.sah_before));
            } else {
                now = refit_sah(mine, s, {}, ex).sah;
                const double next = scaled(prev_ms, prev_sah, now);
                const double predicted = now > rebuilt_sah ? trust * (next - scaled(next, now, rebuilt_sah)) : 0;
                CHECK(r.loss_ms == doctest::Approx(loss + predicted).epsilon(1e-12));
                CHECK(r.rebuild_cost_ms == cost);
                CHECK(r.trust == doctest::Approx(trust).epsilon(1e-12));
                CHECK(r.elasticity == e);
                if (loss + predicted >= cost) {
                    want = Decision::rebuild;
                    check = true;
                    check_refit = next;
                }
                streak.refitted(want == Decision::rebuild, loss + predicted >= 2 * cost);
            }
            streak.end(want == Decision::rebuild);
            expect_decision(r, want, why, f, s, mine, rebuilt_sah, rebuilds, refits, now);
            if (want == Decision::rebuild) now = rebuilt_sah;
            if (want == Decision::rebuild) {
                if (f > 0) check_fresh = scaled(prev_ms, prev_sah, rebuilt_sah);
                loss = 0;
                first_pending = true;
            }
            // the caller traces, then reports
            check_exact(dyn.bvh(), tris, 300 + std::uint64_t(f), "frame " + std::to_string(f));
            dyn.record_trace_ms(trace_ms[f]);
            if (first_pending) {
                first_ms = trace_ms[f];
                first_sah = now;
                first_pending = false;
            } else if (now >= 1.2 * first_sah) {
                const double raw = std::log(trace_ms[f] / first_ms) / std::log(now / first_sah);
                e = std::clamp(raw, 0.125, 1.0);
                ++measured_e;
                clamped_e += raw != e;
            }
            if (check) {
                const double share = (check_refit - trace_ms[f]) / (check_refit - check_fresh);
                if (check_refit > check_fresh) trust = std::max(0.125, 0.5 * trust + 0.5 * std::clamp(share, 0.0, 1.0));
                check = false;
                ++checks;
            }
            if (now > rebuilt_sah) loss += trust * (trace_ms[f] - scaled(trace_ms[f], now, rebuilt_sah));
            prev_ms = trace_ms[f];
            prev_sah = now;
        }
        CHECK(rebuilds >= 3);
        CHECK(refits >= 3);
        CHECK(checks >= 2);
        CHECK(streaks >= 2);
        CHECK(trust < 1);   // the script's times after rebuilds do not show the whole predicted saving
        CHECK(measured_e >= 2);   // the elasticity was measured, once at least inside its bounds
        CHECK(measured_e > clamped_e);
    }
    // Without reported trace times the rule is sah_growth's; bad trace times are ignored; bad costs throw.
    Dynamic<builder::lbvh, Node<>, prim::copied, exec::serial> quiet({.rule = RebuildRule::amortized, .rebuild_threshold = 0});
    for (int f = 0; f < 3; ++f) {
        const FrameReport r = quiet.update(exploding(base, f));
        CHECK(r.decision == Decision::rebuild);
        CHECK(r.reason == (f == 0 ? Reason::first_frame : Reason::sah_growth));
        quiet.record_trace_ms(std::numeric_limits<double>::quiet_NaN());
        quiet.record_trace_ms(-1);
    }
    CHECK_THROWS_WITH_AS(Dynamic<>({.rebuild_ms = -1.0}), doctest::Contains("cfg.rebuild_ms"), std::invalid_argument);
    for (const double e : {0.0, 0.1, 1.5, std::numeric_limits<double>::quiet_NaN()})
        CHECK_THROWS_WITH_AS(Dynamic<>({.initial_elasticity = e}), doctest::Contains("cfg.initial_elasticity"), std::invalid_argument);
    CHECK_NOTHROW(Dynamic<>({.initial_elasticity = 0.125}));
}

TEST_CASE("Dynamic: threshold 0 rebuilds every frame, +inf never rebuilds for SAH growth; bad thresholds throw") {
    const auto base = sphere(8, 16);
    Dynamic<builder::lbvh, Node<>, prim::copied, exec::serial> always({.rebuild_threshold = 0});
    Dynamic<builder::lbvh, Node<>, prim::copied, exec::serial> never({.rebuild_threshold = std::numeric_limits<double>::infinity()});
    for (int f = 0; f < 6; ++f) {
        const auto tris = exploding(base, f);
        CHECK(always.update(tris).decision == Decision::rebuild);
        const FrameReport r = never.update(tris);
        CHECK(r.decision == (f == 0 ? Decision::rebuild : Decision::refit));
        check_exact(never.bvh(), tris, 7, "never");
        check_exact(always.bvh(), tris, 7, "always");
    }
    CHECK(never.sah() > never.rebuild_sah());
    // Rebuilding every frame is a streak from frame 3 on: no refit, and every 4th frame of the run
    // (probe_every = 4) refits to check; probe_every = 0 refits every frame.
    Dynamic<builder::lbvh, Node<>, prim::copied, exec::serial> probing({.rebuild_threshold = 0, .probe_every = 4});
    Dynamic<builder::lbvh, Node<>, prim::copied, exec::serial> refitting({.rebuild_threshold = 0, .probe_every = 0});
    const Reason want[] = {Reason::first_frame, Reason::sah_growth, Reason::sah_growth, Reason::streak, Reason::streak,
                           Reason::streak, Reason::sah_growth, Reason::streak, Reason::streak, Reason::streak, Reason::sah_growth};
    for (int f = 0; f < 11; ++f) {
        CAPTURE(f);
        const auto tris = exploding(base, f);
        const FrameReport a = probing.update(tris), b = refitting.update(tris);
        CHECK(a.decision == Decision::rebuild);
        CHECK(a.reason == want[f]);
        CHECK(std::isnan(a.sah_before) == (a.reason != Reason::sah_growth));
        CHECK(b.reason == (f == 0 ? Reason::first_frame : Reason::sah_growth));
        CHECK(same_bits(a.sah_after, b.sah_after));   // the same trees either way
        check_exact(probing.bvh(), tris, 9, "probing");
    }
    CHECK_THROWS_WITH_AS(Dynamic<>({.rebuild_threshold = -1.0}), doctest::Contains("cfg.rebuild_threshold"), std::invalid_argument);
    CHECK_THROWS_AS(Dynamic<>({.rebuild_threshold = std::numeric_limits<double>::quiet_NaN()}), std::invalid_argument);
}

TEST_CASE("Dynamic: a changed triangle count or set of non-finite triangles forces a rebuild") {
    for_each_executor([&](auto ex) {
        using E = decltype(ex);
        CAPTURE(executor_name<E>());
        Dynamic<builder::ploc, Node<>, prim::indexed, E> dyn({.rebuild_threshold = 1e9}, ex);
        auto tris = sphere(10, 20);
        CHECK(dyn.update(tris).decision == Decision::rebuild);
        CHECK(dyn.update(tris).decision == Decision::refit);
        tris.pop_back();
        FrameReport r = dyn.update(tris);
        CHECK(r.decision == Decision::rebuild);
        CHECK(r.reason == Reason::topology);
        CHECK(std::isnan(r.sah_before));
        CHECK(dyn.bvh().primitive_count == tris.size());
        check_exact(dyn.bvh(), tris, 11, "after count change");
        // A triangle becomes NaN: rebuilt (left out); becomes finite again: rebuilt (back in the tree).
        const Trianglef keep = tris[5];
        tris[5].p1.y = std::numeric_limits<float>::quiet_NaN();
        r = dyn.update(tris);
        CHECK(r.decision == Decision::rebuild);
        CHECK(r.reason == Reason::finiteness);
        CHECK(dyn.bvh().excluded == 1);
        check_exact(dyn.bvh(), tris, 12, "with a NaN triangle");
        CHECK(dyn.update(tris).decision == Decision::refit);
        tris[5] = keep;
        r = dyn.update(tris);
        CHECK(r.reason == Reason::finiteness);
        CHECK(dyn.bvh().excluded == 0);
        check_exact(dyn.bvh(), tris, 13, "NaN triangle restored");
        // Empty input is a topology like any other.
        r = dyn.update(std::span<const Trianglef>());
        CHECK(r.decision == Decision::rebuild);
        CHECK(dyn.bvh().empty());
        CHECK_FALSE(intersect(dyn.bvh(), std::span<const Trianglef>(), Rayf{{0, 0, -5}, {0, 0, 1}}));
    });
}

TEST_CASE("Dynamic async: the background tree is swapped in, refitted to the frame, and every frame is exact") {
    const auto base = sphere(12, 24);
    SUBCASE("deterministic: waiting after each frame, the swap comes the frame after the rebuild started") {
        const exec::serial ex;
        Dynamic<builder::ploc, Node<>, prim::indexed, exec::serial> dyn({.rebuild_threshold = 1.3, .async = true}, ex);
        std::vector<Trianglef> started_over;   // the triangles of the frame the running rebuild copied
        int swaps = 0;
        for (int f = 0; f < 14; ++f) {
            const auto tris = exploding(base, f);
            const std::span<const Trianglef> s(tris);
            const bool pending = dyn.rebuild_pending();
            const FrameReport r = dyn.update(s);
            CAPTURE(f);
            if (f == 0) CHECK(r.decision == Decision::rebuild);
            else if (pending) {
                // Expected: a fresh build over the copied frame, refitted to this one.
                CHECK(r.decision == Decision::swap);
                auto expect = ploc::build<Node<>, prim::indexed>(std::span<const Trianglef>(started_over), {}, ex);
                const double fresh = sah_cost(expect, {}, ex);
                CHECK(same_bits(r.sah_after, refit_sah(expect, s, {}, ex).sah));
                CHECK(same_bits(r.sah_rebuilt, fresh));
                CHECK(dyn.bvh().nodes.size() == expect.nodes.size());
                ++swaps;
            } else {
                CHECK(r.decision == Decision::refit);
                CHECK(r.rebuild_started == (r.sah_before > 1.3 * r.sah_rebuilt));
            }
            if (r.rebuild_started) started_over = tris;
            CHECK(dyn.rebuild_pending() == r.rebuild_started);
            CHECK(structure_problems(dyn.bvh(), tris) == "");
            check_exact(dyn.bvh(), tris, 200 + std::uint64_t(f), "async frame " + std::to_string(f));
            dyn.wait_for_rebuild();
        }
        CHECK(swaps >= 2);
    }
    SUBCASE("free-running on every executor: exact each frame while the rebuild runs; a swap happens") {
        for_each_executor([&](auto ex) {
            using E = decltype(ex);
            CAPTURE(executor_name<E>());
            Dynamic<builder::ploc, Node<>, prim::copied, E> dyn({.rebuild_threshold = 1.1, .async = true}, ex);
            int swaps = 0, started = 0;
            for (int f = 0; f < 24; ++f) {
                const auto tris = exploding(base, f);
                const FrameReport r = dyn.update(tris);
                swaps += r.decision == Decision::swap;
                started += r.rebuild_started;
                CHECK((r.decision != Decision::rebuild || f == 0));
                check_exact(dyn.bvh(), tris, 300 + std::uint64_t(f), "free-running frame " + std::to_string(f));
                if (f == 20) dyn.wait_for_rebuild();   // at least one swap below, however slow the machine
            }
            CHECK(started >= 1);
            CHECK(swaps >= 1);
            // A topology change while a rebuild runs: the running one is dropped, the new count rebuilt.
            auto tris = exploding(base, 30);
            dyn.update(tris);
            tris.resize(tris.size() / 2);
            const FrameReport r = dyn.update(tris);
            CHECK(r.decision == Decision::rebuild);
            CHECK_FALSE(dyn.rebuild_pending());
            check_exact(dyn.bvh(), tris, 400, "after count change");
        });
    }
    SUBCASE("moving a policy with a running rebuild keeps it valid") {
        Dynamic<builder::ploc, Node<>, prim::indexed, exec::serial> a({.rebuild_threshold = 0, .async = true});
        auto tris = exploding(base, 3);
        a.update(tris);
        a.update(exploding(base, 4));   // threshold 0: starts a rebuild
        Dynamic<builder::ploc, Node<>, prim::indexed, exec::serial> b(std::move(a));
        tris = exploding(base, 5);
        b.wait_for_rebuild();
        CHECK(b.update(tris).decision == Decision::swap);
        check_exact(b.bvh(), tris, 500, "moved");
    }
}
