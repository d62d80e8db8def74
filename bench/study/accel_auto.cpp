// The `auto` strategy's Accel (see auto_accel.hpp), on every executor.
#include "auto_accel.hpp"

#include <chrono>
#include <cmath>
#include <stdexcept>
#include <type_traits>

#include <dynbvh/builder.hpp>
#include <dynbvh/dynamic.hpp>
#include <dynbvh/wide_blocks.hpp>

#include "dyn_accel.hpp"

namespace dynbvh::study {

namespace {

const char* decision_name(Decision d) {
    switch (d) {
        case Decision::refit: return "refit";
        case Decision::rebuild: return "rebuild";
        case Decision::swap: return "swap";
    }
    return "?";
}

const char* reason_name(Reason r) {
    switch (r) {
        case Reason::none: return "none";
        case Reason::first_frame: return "first_frame";
        case Reason::topology: return "topology";
        case Reason::finiteness: return "finiteness";
        case Reason::sah_growth: return "sah_growth";
        case Reason::amortized: return "amortized";
        case Reason::rebuild_ready: return "rebuild_ready";
        case Reason::streak: return "streak";
    }
    return "?";
}

template <class B> typename B::config builder_config(const BuilderSpec& spec);
template <> builder::ploc::config builder_config<builder::ploc>(const BuilderSpec& spec) {
    return {.radius = spec.radius, .morton_bits = spec.morton_bits, .leaves = accel_impl::leaf_config(spec)};
}
template <> builder::lbvh::config builder_config<builder::lbvh>(const BuilderSpec& spec) {
    return {.morton_bits = spec.morton_bits, .leaves = accel_impl::leaf_config(spec)};
}

/// dynbvh::Dynamic<B> over the indexed triangles. With blocks (NodeT a WideNode, Prim prim::blocks) the
/// policy holds the traced block tree itself: built, refitted in place and judged by its own SAH, traced
/// as it is. Otherwise the traced wide tree is made from the policy's binary tree each frame.
template <class Exec, class B, class NodeT, class Prim>
class AutoAccel final : public Accel {
    using Trees = accel_impl::Trees<prim::indexed>;
    using Dyn = Dynamic<B, NodeT, Prim, Exec>;
    static constexpr bool holds_blocks = !std::is_same_v<Prim, prim::indexed>;

public:
    AutoAccel(const BuilderSpec& spec, const Exec& ex, const Backend& backend)
        : spec_(spec), ex_(ex), backend_(backend),
          dyn_(typename Dyn::config_type{.rule = spec.amortized ? RebuildRule::amortized : RebuildRule::sah_growth,
                                         .rebuild_threshold = spec.threshold,
                                         .async = spec.async,
                                         .builder = builder_config<B>(spec),
                                         .cost = SahCost{.ct = 3, .ci = 2}},   // the study's SAH column
               ex) {}

    void build(std::span<const Trianglef> tris) override {
        previous_ = std::move(current_);   // freed untimed in release_previous()
        report_ = dyn_.update(tris);
        // The traced tree: the policy's own block tree (blocks=1, the default), or a wide copy of its
        // binary tree, or for wide=0 a copy of the binary tree itself. A wide copy's leaf part is copied
        // after a rebuild or swap (the policy keeps its own for the next refit); after a refit the
        // references are unchanged, so the previous wide tree's leaf part is taken over.
        if constexpr (holds_blocks) {
            if constexpr (Dyn::bvh_type::width == 4) current_.view4 = &dyn_.bvh();
            else current_.view8 = &dyn_.bvh();
        } else {
            const bool same_refs = report_.decision == Decision::refit;
            const auto wide_of = [&]<int W>(auto& wide, auto& before) {
                if (!same_refs || before.empty()) {
                    wide = make_wide<W>(dyn_.bvh(), ex_);
                    return;
                }
                wide = {};
                wide.leaves() = std::move(before.leaves());
                dynbvh::detail::collapse_to_wide<W>(dyn_.bvh(), wide, ex_);
            };
            if (spec_.wide == 4) wide_of.template operator()<4>(current_.wide4, previous_.wide4);
            else if (spec_.wide == 8) wide_of.template operator()<8>(current_.wide8, previous_.wide8);
            else current_.bvh = dyn_.bvh();
        }
    }
    void release_previous() override { previous_ = Trees{}; }
    void trace(std::span<const Trianglef> tris, const RayGen& gen, std::span<std::uint32_t> out) override {
        // The amortized rule's input: this frame's trace time (what a renderer would measure too).
        const auto start = std::chrono::steady_clock::now();
        current_.trace(spec_, backend_, tris, gen, out);
        dyn_.record_trace_ms(std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - start).count());
    }
    std::optional<double> sah() const override { return report_.sah_after; }
    std::optional<std::size_t> memory_bytes() const override { return current_.memory_bytes(spec_); }
    std::optional<StrategyRecord> strategy() const override {
        StrategyRecord s;
        s.decision = decision_name(report_.decision);
        s.reason = reason_name(report_.reason);
        if (std::isfinite(report_.sah_before)) s.sah_before = report_.sah_before;
        s.sah_after = report_.sah_after;
        s.sah_rebuilt = report_.sah_rebuilt;
        s.threshold = spec_.threshold;
        s.rule = spec_.amortized ? "amortized" : "sah";
        s.loss_ms = report_.loss_ms;
        s.rebuild_cost_ms = report_.rebuild_cost_ms;
        s.trust = report_.trust;
        s.elasticity = report_.elasticity;
        s.rebuild_started = report_.rebuild_started;
        return s;
    }
    Hitf intersect(std::span<const Trianglef> tris, const Rayf& r) const override { return current_.intersect(spec_, tris, r); }
    bool occluded(std::span<const Trianglef> tris, const Rayf& r) const override { return current_.occluded(spec_, tris, r); }
    void intersect_packet(std::span<const Trianglef> tris, std::span<const Rayf> rays, std::span<Hitf> out) const override {
        current_.intersect_packet(spec_, tris, rays, out);
    }
    void occluded_packet(std::span<const Trianglef> tris, std::span<const Rayf> rays, std::span<std::uint8_t> out) const override {
        current_.occluded_packet(spec_, tris, rays, out);
    }

private:
    BuilderSpec spec_;
    Exec ex_;
    const Backend& backend_;
    Dyn dyn_;
    FrameReport report_;
    Trees current_, previous_;
};

/// AutoAccel over builder B with the layout spec names: the policy over the 8- or 4-wide block tree
/// (blocks), else over the binary tree.
template <class Exec, class B>
std::unique_ptr<Accel> auto_over(const BuilderSpec& spec, const Exec& ex, const Backend& backend) {
    if (spec.blocks && spec.wide == 8)
        return std::make_unique<AutoAccel<Exec, B, WideNode<float, std::uint32_t, 8>, prim::blocks<8>>>(spec, ex, backend);
    if (spec.blocks && spec.wide == 4)
        return std::make_unique<AutoAccel<Exec, B, WideNode<float, std::uint32_t, 4>, prim::blocks<4>>>(spec, ex, backend);
    return std::make_unique<AutoAccel<Exec, B, Node<>, prim::indexed>>(spec, ex, backend);
}

} // namespace

template <class Exec>
std::unique_ptr<Accel> make_auto_accel(const BuilderSpec& spec, const Exec& ex, const Backend& backend) {
    if (spec.kind != Kind::dynamic) throw std::logic_error("make_auto_accel: " + spec.name() + " is not auto");
    if (spec.precomputed) throw std::invalid_argument("builder " + spec.name() + ": auto traces the indexed triangles only");
    if (spec.over == Kind::lbvh) return auto_over<Exec, builder::lbvh>(spec, ex, backend);
    return auto_over<Exec, builder::ploc>(spec, ex, backend);
}

template std::unique_ptr<Accel> make_auto_accel(const BuilderSpec&, const exec::serial&, const Backend&);
#if defined(_OPENMP)
template std::unique_ptr<Accel> make_auto_accel(const BuilderSpec&, const exec::omp&, const Backend&);
#endif
#if defined(DYNBVH_WITH_TBB)
template std::unique_ptr<Accel> make_auto_accel(const BuilderSpec&, const exec::tbb&, const Backend&);
#endif

} // namespace dynbvh::study
