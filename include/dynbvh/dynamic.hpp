// SPDX-License-Identifier: MIT
/// @file dynamic.hpp
/// A refit-or-rebuild policy holding one tree across the frames of an animation:
/// @code
///   dynbvh::Dynamic<> scene;                       // PLOC, rebuild past 1.3x the last rebuild's SAH
///   for (frame...) {
///       const auto report = scene.update(tris);    // refit, rebuild or swap; report.decision says which
///       auto hit = dynbvh::intersect(scene.bvh(), tris, ray);
///   }
/// @endcode
/// The tree can be the traced layout itself (the W-wide tree with SIMD triangle blocks, wide_blocks.hpp),
/// so that nothing is converted per frame:
/// @code
///   dynbvh::Dynamic<dynbvh::builder::ploc, dynbvh::WideNode<float, std::uint32_t, 8>, dynbvh::prim::blocks<8>> scene;
///   scene.update(tris);                            // build_blocks, or the block tree refitted in place
///   auto hit = dynbvh::intersect(scene.bvh(), tris, ray);   // (packets too: packet.hpp)
/// @endcode
/// Each frame the tree is refitted and its SAH summed in the same passes (refit_sah, refit.hpp; for a
/// block tree wide_blocks.hpp's refit_sah: blocks reloaded, boxes, then the wide tree's SAH, sah.hpp, in
/// one more pass over the nodes; the rules compare that SAH with the block tree's own after its
/// rebuild). Two rules decide when it is rebuilt instead (`DynamicConfig::rule`):
///  - `amortized` (the default, once the caller reports trace times with record_trace_ms()): trace time
///    is taken as growing with the SAH (Goldsmith & Salmon 1987; MacDonald & Booth 1990) as T ~ s^e, so of
///    a frame traced in T ms with SAH s, T (1 - (s_rebuilt / s)^e) is the time the refitted tree lost
///    against a fresh one (s_rebuilt: the SAH right after the last rebuild). The elasticity e starts at
///    `DynamicConfig::initial_elasticity` (1/3) and is measured on the refitted frames themselves: once the
///    SAH has grown by 20 % over the first frame traced after the last (re)build, e = log(T / T1) /
///    log(s / s1) of the current frame against that first one, kept in [1/8, 1]
///    (`FrameReport::elasticity`; packets, caches and the scene's depth complexity make trace time grow
///    more slowly than the SAH, often at a third of its rate). The losses are summed since the last rebuild,
///    this frame's predicted one added; once that sum reaches what a rebuild costs (its measured time, or
///    `rebuild_ms`), the tree is rebuilt. This is the ski-rental rule: a rebuild is bought once refitting
///    has cost as much, so the policy never pays much more than the better of always refitting and
///    always rebuilding, at any resolution, without being told which. The model is also
///    checked after each such rebuild: the first traced frame of the fresh tree gives the saving
///    actually measured against the one predicted, and their ratio (kept in [1/8, 1], averaged over
///    rebuilds) scales every later loss estimate (`FrameReport::trust`).
///  - `sah_growth`: rebuild when the refitted SAH exceeds `rebuild_threshold` times s_rebuilt (also the
///    amortized rule's fallback while no trace time has been reported).
/// A changed triangle count (topology), or a changed set of non-finite triangles (the builders leave
/// those out, and refit cannot add them back), rebuilds at once under both rules.
///
/// Rebuild streaks: when the scene moves so much that the rule rebuilds at the first refit after a
/// rebuild, by a clear margin (the loss at least twice the rebuild cost; for sah_growth the SAH at
/// least twice the threshold's limit), two frames in a row (n-body, explosions), the refit and SAH
/// evaluation before each rebuild are wasted work. The policy then rebuilds without them
/// (`Reason::streak`), and every `DynamicConfig::probe_every`-th frame of the run refits to check that
/// the rule still rebuilds by that margin; the first probe that does not ends the run. The margin
/// keeps borderline scenes, where the rule alternates, out of streaks. (Synchronous rebuilds only.)
///
/// Asynchronous rebuild (Ize, Wald, Parker 2007, "Asynchronous BVH Construction for Ray Tracing
/// Dynamic Scenes on Parallel Multi-Core Architectures"): with `async`, a rebuild runs on a background
/// std::thread over a copy of the frame's triangles while the refitted old tree serves the following
/// frames; the first update() after it finished takes the new tree, refits it to that frame and swaps
/// it in. At most one rebuild runs at a time.
/// Synchronisation: the background thread touches only what it owns (the triangle copy, copies of the
/// builder's config and of the executor) and a result slot guarded by a mutex; the tree it built is
/// taken after joining the thread. The scratch cache the builders allocate from is mutex-guarded
/// (detail/scratch.hpp). One Dynamic is used by one thread at a time (update() and the accessors are
/// not synchronised with each other).
#pragma once

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstddef>
#include <cstdint>
#include <exception>
#include <limits>
#include <memory>
#include <mutex>
#include <optional>
#include <span>
#include <stdexcept>
#include <string>
#include <thread>
#include <type_traits>
#include <utility>
#include <vector>

#include "builder.hpp"
#include "bvh.hpp"
#include "cost.hpp"
#include "executor.hpp"
#include "mesh.hpp"
#include "refit.hpp"
#include "sah.hpp"
#include "wide.hpp"
#include "wide_blocks.hpp"

namespace dynbvh {

/// What update() did with the tree this frame.
enum class Decision : std::uint8_t {
    refit,    ///< the tree was refitted and serves the frame
    rebuild,  ///< a new tree was built over this frame's triangles (synchronously)
    swap,     ///< a background rebuild finished; its tree, refitted to this frame, replaced the old one
};
/// Why update() decided so.
enum class Reason : std::uint8_t {
    none,          ///< refit: the refitted SAH is within the threshold (or a rebuild is already running)
    first_frame,   ///< no tree yet
    topology,      ///< the triangle count changed
    finiteness,    ///< the set of triangles with a NaN or infinite vertex changed
    sah_growth,    ///< the refitted SAH exceeded rebuild_threshold times the last rebuild's
    amortized,     ///< the trace time lost to refitting since the last rebuild reached a rebuild's cost
    rebuild_ready, ///< swap: the background rebuild finished
    streak,        ///< rebuilt without refitting first: a run of rebuilds at every frame (see the file comment)
};

/// One frame's decision. SAHs use the policy's `cost`: after a rebuild sah_cost's value (sah.hpp), after
/// a refit refit_sah's (refit.hpp: the same formula, its terms summed in the refit's order).
struct FrameReport {
    Decision decision = Decision::refit;   ///< what was done
    Reason reason = Reason::none;          ///< why
    /// SAH of the previous frame's tree refitted to this frame (refit and rebuild on SAH growth); for a
    /// swap the SAH the replaced tree had at the previous frame; NaN when there was no tree to refit
    /// (first frame, topology or finiteness change) or it was not refitted (streak).
    double sah_before = std::numeric_limits<double>::quiet_NaN();
    /// SAH of the tree that serves this frame.
    double sah_after = 0;
    /// SAH the serving tree had right after its (last) build: what the threshold multiplies.
    double sah_rebuilt = 0;
    /// Wall-clock time of update() in milliseconds (the background rebuild's time is not included).
    double ms = 0;
    /// Async only: a background rebuild was started this frame (over this frame's triangles).
    bool rebuild_started = false;
    /// Frame number, 0 for the first update().
    std::size_t frame = 0;
    /// Amortized rule: trace time, in ms, the refitted tree is estimated to have lost against a fresh
    /// one since the last rebuild, this frame's predicted loss included (0 without reported trace times).
    double loss_ms = 0;
    /// Amortized rule: what a rebuild is taken to cost, in ms (the last rebuild's measured time, or
    /// DynamicConfig::rebuild_ms).
    double rebuild_cost_ms = 0;
    /// Amortized rule: the share of the SAH-predicted savings that rebuilds measurably delivered so far
    /// (1 until a rebuild has been checked; in [1/8, 1]); it scales loss_ms.
    double trust = 1;
    /// Amortized rule: the elasticity e of trace time to the SAH the loss estimates use (T ~ s^e, in
    /// [1/8, 1]; 1 until measured, see the file comment).
    double elasticity = 1;
};

/// How Dynamic decides to rebuild a refitted tree (see dynamic.hpp's file comment).
enum class RebuildRule : std::uint8_t {
    amortized,    ///< rebuild once the trace time lost to refitting reaches a rebuild's cost (default)
    sah_growth,   ///< rebuild past rebuild_threshold times the last rebuild's SAH
};

/// Knobs of Dynamic. Designated-initialiser friendly: `{.rebuild_threshold = 1.5, .async = true}`.
template <class BuilderConfig>
struct DynamicConfig {
    /// The rule. Default amortized, which needs the caller's trace time each frame
    /// (Dynamic::record_trace_ms); until the first one it applies sah_growth.
    RebuildRule rule = RebuildRule::amortized;
    /// sah_growth: rebuild when the refitted tree's SAH exceeds this many times the SAH right after the
    /// last rebuild. 0 rebuilds every frame, +inf never rebuilds for SAH growth (always refit). Default 1.3.
    /// NaN or negative values are rejected (std::invalid_argument).
    double rebuild_threshold = 1.3;
    /// amortized: what a rebuild costs, in ms. 0 (default): the measured wall time of the last rebuild
    /// (build + SAH, on the calling thread or in the background). Negative or NaN: std::invalid_argument.
    double rebuild_ms = 0;
    /// amortized: the elasticity e (trace time ~ SAH^e) the loss estimates assume until the refitted
    /// frames have measured one (see the file comment). Default 1/3, the middle of what the built-in scenes
    /// measure (0.12-0.46 in the study: primary rays, packets and caches make trace time grow far more
    /// slowly than the SAH); 1 assumes trace time proportional to the SAH, which rebuilt scenes whose
    /// trace time barely grew (cloth, 8 frames spread over the animation: 1.11x the better of always
    /// refitting and always rebuilding). In [1/8, 1]; others: std::invalid_argument.
    double initial_elasticity = 1.0 / 3.0;
    /// Rebuild on a background thread while refitted trees serve the frames (Ize et al. 2007). Default off.
    bool async = false;
    /// Rebuild streaks (see the file comment): once two frames in a row rebuilt at their first refit by
    /// a clear margin, rebuild without refitting, except every probe_every-th frame of the run, which
    /// refits and applies the rule. Default 8; 0 or 1 always refits first. Not used with async.
    unsigned probe_every = 8;
    /// The builder's own knobs.
    BuilderConfig builder{};
    /// Ct and Ci of the SAH that the rule compares.
    SahCost cost{};
};

namespace detail {
/// The tree a Dynamic holds: Bvh<NodeT, Prim>, or for a wide node with SIMD triangle blocks
/// (WideNode<float, Index, W> and prim::blocks<L>) the traced layout WideBvh<NodeT, Prim> itself.
template <class NodeT, class Prim>
struct dynamic_tree {
    using type = Bvh<NodeT, Prim>;
    static constexpr bool blocks = false;
};
template <class S, class I, int W, int L>
struct dynamic_tree<WideNode<S, I, W>, prim::blocks<L>> {
    static_assert(std::is_same_v<S, float> && std::is_same_v<I, std::uint32_t>,
                  "dynbvh::Dynamic over block trees: WideNode<float, std::uint32_t, W> (the builders' traced layout)");
    using type = WideBvh<WideNode<S, I, W>, prim::blocks<L>>;
    static constexpr bool blocks = true;
};
} // namespace detail

/// Refit-or-rebuild policy over one triangle array that changes from frame to frame (see the file
/// comment). update() costs a refit that also sums the SAH (refit_sah: O(nodes + references), no second
/// pass), plus a build and an SAH evaluation when it rebuilds
/// synchronously; async adds a copy of the triangles when a rebuild starts.
/// @tparam Builder builder policy (builder.hpp): builder::ploc (default), builder::lbvh, builder::binned_sah
/// @tparam NodeT, Prim the tree's node layout and primitive policy (bvh.hpp), or the traced layout:
///         `WideNode<float, std::uint32_t, W>` with `prim::blocks<L>` holds the W-wide tree with SIMD
///         triangle blocks (wide_blocks.hpp) itself, built by Builder::build_blocks, refitted in place
///         (refit_sah of the block tree) and judged by the wide tree's SAH (sah_cost of a WideBvh): no
///         binary tree to refit and convert each frame.
///         `Dynamic<builder::ploc, WideNode<float, std::uint32_t, 8>, prim::blocks<8>>` traces bvh() directly.
/// @tparam Exec threading backend (executor.hpp), also used by the background rebuild
template <class Builder = builder::ploc, class NodeT = Node<>, class Prim = prim::indexed,
          class Exec = exec::default_executor>
class Dynamic {
public:
    using scalar_type = typename NodeT::scalar_type;              ///< the tree's scalar (float by default)
    using triangle_type = Triangle<scalar_type>;                  ///< the input triangle
    using bvh_type = typename detail::dynamic_tree<NodeT, Prim>::type;   ///< the tree held across frames
    using config_type = DynamicConfig<typename Builder::config>;  ///< the policy's knobs

    /// A policy with no tree yet (the first update() builds). Throws std::invalid_argument when
    /// cfg.rebuild_threshold or cfg.rebuild_ms is NaN or negative, or cfg.initial_elasticity lies outside [1/8, 1].
    explicit Dynamic(const config_type& cfg = {}, const Exec& ex = {}) : cfg_(cfg), ex_(ex), elasticity_(cfg.initial_elasticity) {
        if (!(cfg.rebuild_threshold >= 0))
            throw std::invalid_argument("dynbvh::Dynamic: cfg.rebuild_threshold is " + std::to_string(cfg.rebuild_threshold) +
                                        "; it must be >= 0 (0 rebuilds every frame, +inf never)");
        if (!(cfg.rebuild_ms >= 0))
            throw std::invalid_argument("dynbvh::Dynamic: cfg.rebuild_ms is " + std::to_string(cfg.rebuild_ms) +
                                        "; it must be >= 0 (0: the measured time of the last rebuild)");
        if (!(cfg.initial_elasticity >= min_trust && cfg.initial_elasticity <= 1.0))
            throw std::invalid_argument("dynbvh::Dynamic: cfg.initial_elasticity is " + std::to_string(cfg.initial_elasticity) +
                                        "; it must lie in [0.125, 1] (trace time ~ SAH^e)");
    }
    /// Takes over `o`'s tree and its running background rebuild, if any.
    Dynamic(Dynamic&&) noexcept = default;
    /// Waits for this policy's own background rebuild, then takes over `o`'s state.
    Dynamic& operator=(Dynamic&& o) noexcept {
        if (this != &o) {
            drop_background();
            tree_ = std::move(o.tree_);
            cfg_ = std::move(o.cfg_);
            ex_ = std::move(o.ex_);
            built_ = o.built_;
            sah_ = o.sah_;
            sah_rebuilt_ = o.sah_rebuilt_;
            build_ms_ = o.build_ms_;
            loss_ms_ = o.loss_ms_;
            trace_ms_ = o.trace_ms_;
            trace_sah_ = o.trace_sah_;
            trust_ = o.trust_;
            elasticity_ = o.elasticity_;
            first_ms_ = o.first_ms_;
            first_sah_ = o.first_sah_;
            first_pending_ = o.first_pending_;
            check_ = o.check_;
            check_refit_ms_ = o.check_refit_ms_;
            check_fresh_ms_ = o.check_fresh_ms_;
            excluded_ids_ = std::move(o.excluded_ids_);
            frame_ = o.frame_;
            fresh_ = o.fresh_;
            streak_ = o.streak_;
            probes_ = o.probes_;
            job_ = std::move(o.job_);
        }
        return *this;
    }
    Dynamic(const Dynamic&) = delete;
    Dynamic& operator=(const Dynamic&) = delete;
    /// Waits for a background rebuild still running (its result is dropped).
    ~Dynamic() { drop_background(); }

    /// Brings the tree to this frame's triangles `tris` (any count; the array the caller traces with
    /// until the next update(), for prim::indexed) and says how. `tris` is not modified nor kept.
    FrameReport update(std::span<const triangle_type> tris) { return update_from(tris); }

    /// The same over an indexed mesh read in place (mesh.hpp), typically one view whose vertices move
    /// from frame to frame: the decisions and trees the span of make_triangles(vertices, indices) would
    /// give, without that copy (an async rebuild still copies the triangles it builds over). A refit
    /// frame allocates nothing when every vertex is finite.
    template <class Index>
    FrameReport update(const MeshView<scalar_type, Index>& mesh) { return update_from(mesh); }

    /// Tells the amortized rule how long the caller traced the current tree (the one the last update()
    /// left) this frame, in ms; call it once per frame, after tracing. A negative, NaN or infinite `ms`
    /// is ignored. It adds that frame's estimated loss, ms (1 - (rebuild_sah() / sah())^e), to the sum the
    /// rule compares, and measures e on refitted frames (see the file comment).
    void record_trace_ms(double ms) noexcept {
        if (!(ms >= 0) || !std::isfinite(ms) || !built_) return;
        if (first_pending_) {
            // Step: the first frame traced since the last (re)build or swap: the elasticity's reference.
            first_ms_ = ms;
            first_sah_ = sah_;
            first_pending_ = false;
        } else if (first_ms_ > 0 && ms > 0 && sah_ >= elasticity_growth * first_sah_) {
            elasticity_ = std::clamp(std::log(ms / first_ms_) / std::log(sah_ / first_sah_), min_trust, 1.0);
        }
        if (check_) {
            // Step: the first frame traced after an amortized rebuild: measured vs predicted saving.
            const double predicted = check_refit_ms_ - check_fresh_ms_, measured = check_refit_ms_ - ms;
            if (predicted > 0) trust_ = std::max(min_trust, 0.5 * trust_ + 0.5 * std::clamp(measured / predicted, 0.0, 1.0));
            check_ = false;
        }
        trace_ms_ = ms;
        trace_sah_ = sah_;
        loss_ms_ += trust_ * lost(ms, sah_);
    }

    /// The tree serving the current frame (empty before the first update()).
    const bvh_type& bvh() const noexcept { return tree_; }
    /// SAH of the current tree at the current frame.
    double sah() const noexcept { return sah_; }
    /// SAH the current tree had right after its build (what rebuild_threshold multiplies).
    double rebuild_sah() const noexcept { return sah_rebuilt_; }
    /// Whether a background rebuild is running or finished but not yet swapped in.
    bool rebuild_pending() const noexcept { return job_ != nullptr; }
    /// Blocks until the background rebuild (if any) has finished; the next update() swaps it in.
    void wait_for_rebuild() {
        if (job_ && job_->thread.joinable()) job_->thread.join();
    }
    /// The policy's knobs.
    const config_type& config() const noexcept { return cfg_; }
    /// Number of update() calls so far.
    std::size_t frames() const noexcept { return frame_; }

private:
    struct Job {
        bvh_type tree;
        double sah = 0;
        double ms = 0;   // build + SAH, wall clock
        std::vector<std::uint32_t> excluded_ids;
    };
    /// A background rebuild: its thread and its result slot (heap-allocated, so the policy may move).
    struct Background {
        std::thread thread;
        std::mutex mutex;
        bool done = false;                // guarded by mutex
        std::optional<Job> result;        // guarded by mutex
        std::exception_ptr error;         // guarded by mutex
    };

    /// The least trust in the SAH model (and least elasticity), so that a tree degrading without bound is
    /// still rebuilt.
    static constexpr double min_trust = 0.125;
    /// SAH growth over the first traced frame of a run from which the elasticity is measured (below it,
    /// the ratio of two noisy trace times says little).
    static constexpr double elasticity_growth = 1.2;
    /// Trace time predicted for SAH `to` from `ms` measured at SAH `from`: ms (to / from)^e.
    double scaled(double ms, double from, double to) const noexcept {
        return elasticity_ == 1.0 ? ms * to / from : ms * std::pow(to / from, elasticity_);
    }
    /// Of `ms` traced with SAH `sah`, what a fresh tree (SAH sah_rebuilt_) would have saved.
    double lost(double ms, double sah) const noexcept {
        return sah > sah_rebuilt_ && sah > 0 ? ms - scaled(ms, sah, sah_rebuilt_) : 0.0;
    }
    double rebuild_cost() const noexcept { return cfg_.rebuild_ms > 0 ? cfg_.rebuild_ms : build_ms_; }
    bool amortizing() const noexcept { return cfg_.rule == RebuildRule::amortized && trace_sah_ > 0; }
    /// The rule on the refitted tree (sah_ current); r gets the reason and the amortized figures.
    bool grown(FrameReport& r) const noexcept {
        if (!amortizing()) {
            r.reason = Reason::sah_growth;
            return sah_ > cfg_.rebuild_threshold * sah_rebuilt_;
        }
        // This frame's loss predicted from the last traced frame's time, scaled by the SAH.
        const double predicted = trust_ * lost(scaled(trace_ms_, trace_sah_, sah_), sah_);
        r.loss_ms = loss_ms_ + predicted;
        r.rebuild_cost_ms = rebuild_cost();
        r.trust = trust_;
        r.elasticity = elasticity_;
        r.reason = Reason::amortized;
        return r.loss_ms >= r.rebuild_cost_ms;
    }

    /// update() over any triangle source (a span or a MeshView): one code path.
    template <class Source>
    FrameReport update_from(const Source tris) {
        const auto start = std::chrono::steady_clock::now();
        FrameReport r;
        r.frame = frame_++;
        // The set of non-finite triangles is looked up front unless the refit can tell: when the count
        // is unchanged and the last build left nothing out, the tree references every triangle, so a
        // refit reads them all and counts the non-finite ones (refit_sah) in the same pass.
        const bool refit_reads_all = built_ && tris.size() == tree_.primitive_count && excluded_ids_.empty();
        std::vector<std::uint32_t> bad;
        if (!refit_reads_all) bad = nonfinite_ids(tris);
        const auto rebuild_for = [&](Reason why) {
            r.reason = why;
            drop_background();
            rebuild_now(tris, std::move(bad));
            r.decision = Decision::rebuild;
            streak_ = probes_ = 0;
        };
        // A refit that met a non-finite triangle: the set changed (none was left out before).
        const auto became_nonfinite = [&](const RefitReport& rep) {
            if (!refit_reads_all || rep.nonfinite == 0) return false;
            bad = nonfinite_ids(tris);
            r.sah_before = std::numeric_limits<double>::quiet_NaN();
            rebuild_for(Reason::finiteness);
            return true;
        };
        if (!built_ || tris.size() != tree_.primitive_count || (!refit_reads_all && bad != excluded_ids_)) {
            rebuild_for(!built_ ? Reason::first_frame : tris.size() != tree_.primitive_count ? Reason::topology : Reason::finiteness);
        } else if (streaking()) {
            // Step: a run of rebuilds at every frame: rebuild without the refit the rule would waste.
            if (refit_reads_all) bad = nonfinite_ids(tris);
            if (bad != excluded_ids_) {
                rebuild_for(Reason::finiteness);
            } else {
                rebuild_now(tris, std::move(bad));
                r.decision = Decision::rebuild;
                r.reason = Reason::streak;
                if (amortizing()) {   // (what grown() reports under this rule)
                    r.rebuild_cost_ms = rebuild_cost();
                    r.trust = trust_;
                    r.elasticity = elasticity_;
                }
                ++probes_;
            }
        } else if (std::optional<Job> job = take_finished(); job && job->excluded_ids == excluded_ids_) {
            // Step: swap in the background tree, refitted to this frame.
            r.sah_before = sah_;
            tree_ = std::move(job->tree);
            const RefitReport rep = refit_sah(tree_, tris, cfg_.cost, ex_);
            if (!became_nonfinite(rep)) {
                sah_rebuilt_ = job->sah;
                sah_ = rep.sah;
                build_ms_ = job->ms;
                loss_ms_ = 0;
                r.decision = Decision::swap;
                first_pending_ = true;
                FrameReport rule;
                if (grown(rule)) start_background(tris, r);
                r.reason = Reason::rebuild_ready;
                r.rebuild_cost_ms = rebuild_cost();
            }
        } else {
            // Step: refit (with the SAH in the same passes), then apply the rule.
            const bool fresh = fresh_;
            const RefitReport rep = refit_sah(tree_, tris, cfg_.cost, ex_);
            fresh_ = false;
            if (!became_nonfinite(rep)) {
                sah_ = rep.sah;
                r.sah_before = sah_;
                probes_ = 0;
                const bool rebuild = grown(r);
                streak_ = rebuild && fresh && clearly(r) && !cfg_.async ? streak_ + 1 : 0;
                if (rebuild) {
                    if (cfg_.async) {
                        if (!job_) start_background(tris, r);
                        else r.reason = Reason::none;   // one is running already: keep refitting
                    } else {
                        // What this frame's trace would take with the refitted tree, and with a fresh one
                        // (by the SAH): checked against the measured time in record_trace_ms().
                        const double refit_ms = trace_sah_ > 0 ? scaled(trace_ms_, trace_sah_, sah_) : 0;
                        if (refit_reads_all) bad = excluded_ids_;   // (empty: the refit found every triangle finite)
                        rebuild_now(tris, std::move(bad));
                        r.decision = Decision::rebuild;
                        if (r.reason == Reason::amortized) {
                            check_ = true;
                            check_refit_ms_ = refit_ms;
                            check_fresh_ms_ = scaled(trace_ms_, trace_sah_, sah_);
                        }
                    }
                } else {
                    r.reason = Reason::none;
                }
            }
        }
        r.sah_after = sah_;
        r.sah_rebuilt = sah_rebuilt_;
        r.ms = std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - start).count();
        return r;
    }

    /// Indices of the triangles with a NaN or infinite vertex, ascending (the builders exclude them).
    template <class Source>
    std::vector<std::uint32_t> nonfinite_ids(const Source tris) const {
        const std::size_t count = ex_.reduce(std::size_t(0), tris.size(), std::size_t(0),
                                             [&](std::size_t i) { return std::size_t(!tris[i].is_finite()); },
                                             [](std::size_t a, std::size_t b) { return a + b; });
        std::vector<std::uint32_t> ids;
        if (count == 0) return ids;
        ids.reserve(count);
        for (std::size_t i = 0; i < tris.size(); ++i)
            if (!tris[i].is_finite()) ids.push_back(static_cast<std::uint32_t>(i));
        return ids;
    }

    /// A new tree over `tris`: the builder's tree, or its traced layout (see the class comment).
    template <class Source>
    static bvh_type build_tree(const Source& tris, const typename Builder::config& cfg, const Exec& ex) {
        if constexpr (detail::dynamic_tree<NodeT, Prim>::blocks)
            return Builder::template build_blocks<bvh_type::width, bvh_type::block_lanes>(tris, cfg, ex);
        else
            return Builder::template build<NodeT, Prim>(tris, cfg, ex);
    }

    template <class Source>
    void rebuild_now(const Source tris, std::vector<std::uint32_t> bad) {
        const auto start = std::chrono::steady_clock::now();
        tree_ = build_tree(tris, cfg_.builder, ex_);
        sah_ = sah_rebuilt_ = sah_cost(tree_, cfg_.cost, ex_);
        build_ms_ = std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - start).count();
        loss_ms_ = 0;
        excluded_ids_ = std::move(bad);
        built_ = true;
        fresh_ = true;
        first_pending_ = true;
    }

    /// Whether the rule's rebuild this frame (r from grown()) is by the streak margin (see the file comment).
    bool clearly(const FrameReport& r) const noexcept {
        if (r.reason == Reason::amortized) return r.loss_ms >= 2 * r.rebuild_cost_ms;
        return sah_ >= 2 * cfg_.rebuild_threshold * sah_rebuilt_;
    }
    /// Whether this frame rebuilds as part of a streak (see the file comment): two rebuilds in a row at
    /// the first refit, and this is not the run's probe_every-th frame.
    bool streaking() const noexcept {
        return !cfg_.async && cfg_.probe_every > 1 && streak_ >= 2 && probes_ + 1 < cfg_.probe_every;
    }

    /// Starts the background rebuild over a copy of `tris` (the caller may change its triangles after update()).
    template <class Source>
    void start_background(const Source tris, FrameReport& r) {
        auto bg = std::make_unique<Background>();
        Background* slot = bg.get();
        std::vector<triangle_type> copy;
        copy.reserve(tris.size());
        for (std::size_t i = 0; i < tris.size(); ++i) copy.push_back(tris[i]);
        std::vector<std::uint32_t> bad = excluded_ids_;
        bg->thread = std::thread([slot, copy = std::move(copy), bad = std::move(bad), cfg = cfg_, ex = ex_]() mutable {
            std::optional<Job> job;
            std::exception_ptr error;
            try {
                const auto start = std::chrono::steady_clock::now();
                job.emplace();
                job->tree = build_tree(std::span<const triangle_type>(copy), cfg.builder, ex);
                job->sah = sah_cost(job->tree, cfg.cost, ex);
                job->ms = std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - start).count();
                job->excluded_ids = std::move(bad);
            } catch (...) {
                error = std::current_exception();
                job.reset();
            }
            std::lock_guard lock(slot->mutex);
            slot->result = std::move(job);
            slot->error = error;
            slot->done = true;
        });
        job_ = std::move(bg);
        r.rebuild_started = true;
    }

    /// The finished background rebuild, if there is one (its thread joined); rethrows its exception.
    std::optional<Job> take_finished() {
        if (!job_) return std::nullopt;
        {
            std::lock_guard lock(job_->mutex);
            if (!job_->done) return std::nullopt;
        }
        if (job_->thread.joinable()) job_->thread.join();   // wait_for_rebuild() may have joined it
        std::unique_ptr<Background> bg = std::move(job_);
        if (bg->error) std::rethrow_exception(bg->error);
        return std::move(bg->result);
    }

    /// Waits for a running background rebuild and forgets it.
    void drop_background() noexcept {
        if (!job_) return;
        if (job_->thread.joinable()) job_->thread.join();
        job_.reset();
    }

    bvh_type tree_;
    config_type cfg_;
    Exec ex_;
    bool built_ = false;
    double sah_ = 0;            // current tree, current frame
    double sah_rebuilt_ = 0;    // current tree right after its build
    double build_ms_ = 0;       // amortized rule: the current tree's build time
    double loss_ms_ = 0;        // amortized rule: trace time lost to refitting since that build
    double trace_ms_ = 0;       // amortized rule: the last reported trace time ...
    double trace_sah_ = 0;      // ... and the SAH of the tree it traced (0: none reported yet)
    double trust_ = 1;          // amortized rule: share of predicted savings that rebuilds delivered
    double elasticity_;         // amortized rule: e of T ~ s^e, measured on refitted frames (cfg.initial_elasticity at first)
    double first_ms_ = 0, first_sah_ = 0;   // the first frame traced since the last (re)build or swap ...
    bool first_pending_ = false;            // ... is still to come
    bool check_ = false;        // the next record_trace_ms() checks the last rebuild's saving ...
    double check_refit_ms_ = 0, check_fresh_ms_ = 0;   // ... against these predictions
    std::vector<std::uint32_t> excluded_ids_;   // non-finite triangles of the current tree's build
    std::size_t frame_ = 0;
    bool fresh_ = false;        // the current tree was built at the previous frame (not refitted since)
    unsigned streak_ = 0;       // rebuilds in a row at the first refit after a rebuild
    unsigned probes_ = 0;       // streak rebuilds since the run's last refit
    std::unique_ptr<Background> job_;
};

} // namespace dynbvh
