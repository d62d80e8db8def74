// DynAccel: the study's Accel over our builders (lbvh, kbvh, ploc, binned-sah, refit) on one executor,
// and the tile loop every Accel traces with. The class is instantiated once per executor in
// accel_<executor>.cpp, so the three heavy instantiations compile in parallel.
#pragma once

#include <memory>
#include <span>
#include <stdexcept>

#include <dynbvh/binned_sah.hpp>
#include <dynbvh/bvh.hpp>
#include <dynbvh/kbvh.hpp>
#include <dynbvh/lbvh.hpp>
#include <dynbvh/ploc.hpp>
#include <dynbvh/refit.hpp>
#include <dynbvh/sah.hpp>
#include <dynbvh/traverse.hpp>
#include <dynbvh/wide.hpp>

#include "builders.hpp"

namespace dynbvh::study {

/// The tracing loop every builder shares: tiles in parallel through the executor, one ray per pixel.
template <class Intersect>
void trace_tiles(const Backend& backend, const RayGen& gen, std::span<std::uint32_t> out, const Intersect& isect) {
    const int w = gen.width();
    backend.for_tasks(gen.tile_count(), [&](std::size_t k) {
        const Tile t = gen.tile(k);
        for (int y = t.y0; y < t.y1; ++y)
            for (int x = t.x0; x < t.x1; ++x) out[std::size_t(y) * std::size_t(w) + std::size_t(x)] = isect(gen.ray(x, y));
    });
}

/// A DynAccel<Exec, prim::indexed or prim::precomputed> for `spec` (one of our builders).
template <class Exec>
std::unique_ptr<Accel> make_dyn_accel(const BuilderSpec& spec, const Exec& ex, const Backend& backend);

namespace accel_impl {

/// Our builders on executor Exec with primitive policy Prim.
template <class Exec, class Prim>
class DynAccel final : public Accel {
public:
    using BvhT = Bvh<Node<>, Prim>;
    using Wide4 = wide_bvh_of<BvhT, 4>;
    using Wide8 = wide_bvh_of<BvhT, 8>;

    DynAccel(const BuilderSpec& spec, const Exec& ex, const Backend& backend) : spec_(spec), ex_(ex), backend_(backend) {}

    void build(std::span<const Trianglef> tris) override {
        previous_ = std::move(bvh_);   // freed untimed in release_previous()
        previous_wide4_ = std::move(wide4_);
        previous_wide8_ = std::move(wide8_);
        build_binary(tris);
        // The 4- or 8-wide tree traced when spec_.wide (timed as part of the build). The binary tree stays
        // (refit and the SAH column use it).
        if (spec_.wide == 4) wide4_ = make_wide<4>(bvh_, ex_);
        if (spec_.wide == 8) wide8_ = make_wide<8>(bvh_, ex_);
    }
    void build_binary(std::span<const Trianglef> tris) {
        const LeafConfig leaves{.max_leaf_size = spec_.max_leaf};
        switch (spec_.kind) {
            case Kind::lbvh:
                bvh_ = lbvh::build<Node<>, Prim>(tris, {.morton_bits = spec_.morton_bits, .leaves = leaves}, ex_);
                break;
            case Kind::refit:
                if (previous_.empty() || previous_.primitive_count != tris.size()) {
                    bvh_ = lbvh::build<Node<>, Prim>(tris, {.morton_bits = spec_.morton_bits, .leaves = leaves}, ex_);
                } else {
                    bvh_ = std::move(previous_);
                    dynbvh::refit(bvh_, tris, ex_);
                }
                break;
            case Kind::ploc:
                bvh_ = ploc::build<Node<>, Prim>(
                    tris, {.radius = spec_.radius, .morton_bits = spec_.morton_bits, .leaves = leaves}, ex_);
                break;
            case Kind::kbvh: {
                const kbvh::Config<kbvh::with_ploc> cfg{
                    .split = {.beta = spec_.beta},
                    .builder = {.radius = spec_.radius, .morton_bits = spec_.morton_bits, .leaves = leaves}};
                bvh_ = kbvh::build<Node<>, Prim>(tris, cfg, ex_);
                break;
            }
            case Kind::binned_sah:
                bvh_ = binned_sah::build<Node<>, Prim>(tris, {.bins = spec_.bins, .leaves = leaves}, ex_);
                break;
            default:
                throw std::logic_error("DynAccel: not one of our builders");
        }
    }
    void release_previous() override {
        previous_ = BvhT{};
        previous_wide4_ = Wide4{};
        previous_wide8_ = Wide8{};
    }

    void trace(std::span<const Trianglef> tris, const RayGen& gen, std::span<std::uint32_t> out) override {
        if (spec_.fast_box && spec_.fast_tri) run<trace::fast>(tris, gen, out);
        else if (spec_.fast_box) run<trace::policy<box::fast, tri::watertight>>(tris, gen, out);
        else if (spec_.fast_tri) run<trace::policy<box::robust, tri::moller_trumbore>>(tris, gen, out);
        else run<trace::robust>(tris, gen, out);
    }
    std::optional<double> sah() const override { return sah_cost(bvh_, SahConfig{.ct = 3, .ci = 2}, ex_); }
    /// The traced tree's bytes (the wide one when spec_.wide).
    std::optional<std::size_t> memory_bytes() const override {
        return with_tree([](const auto& tree) { return tree.memory_bytes(); });
    }
    /// Single-ray queries (effect rays) go through the same tree as trace().
    Hitf intersect(std::span<const Trianglef> tris, const Rayf& r) const override {
        return with_policy([&]<class Policy>() {
            return with_tree([&](const auto& tree) { return dynbvh::intersect<Policy>(tree, tris, r); });
        });
    }
    bool occluded(std::span<const Trianglef> tris, const Rayf& r) const override {
        return with_policy([&]<class Policy>() {
            return with_tree([&](const auto& tree) { return dynbvh::occluded<Policy>(tree, tris, r); });
        });
    }

private:
    /// f.template operator()<Policy>() with the spec's box and triangle tests (single-ray queries).
    template <class F>
    decltype(auto) with_policy(const F& f) const {
        if (spec_.fast_box && spec_.fast_tri) return f.template operator()<trace::fast>();
        if (spec_.fast_box) return f.template operator()<trace::policy<box::fast, tri::watertight>>();
        if (spec_.fast_tri) return f.template operator()<trace::policy<box::robust, tri::moller_trumbore>>();
        return f.template operator()<trace::robust>();
    }

    /// f(tree) with the traced tree: the 4- or 8-wide one, or the binary one for wide=0.
    template <class F>
    decltype(auto) with_tree(const F& f) const {
        if (spec_.wide == 8) return f(wide8_);
        if (spec_.wide == 4) return f(wide4_);
        return f(bvh_);
    }

    template <class Policy>
    void run(std::span<const Trianglef> tris, const RayGen& gen, std::span<std::uint32_t> out) const {
        with_tree([&](const auto& tree) {
            trace_tiles(backend_, gen, out, [&](const Rayf& r) { return dynbvh::intersect<Policy>(tree, tris, r).prim; });
        });
    }

    BuilderSpec spec_;
    const Exec& ex_;
    const Backend& backend_;
    BvhT bvh_, previous_;
    Wide4 wide4_, previous_wide4_;
    Wide8 wide8_, previous_wide8_;
};

} // namespace accel_impl

template <class Exec>
std::unique_ptr<Accel> make_dyn_accel(const BuilderSpec& spec, const Exec& ex, const Backend& backend) {
    if (spec.precomputed) return std::make_unique<accel_impl::DynAccel<Exec, prim::precomputed>>(spec, ex, backend);
    return std::make_unique<accel_impl::DynAccel<Exec, prim::indexed>>(spec, ex, backend);
}

extern template std::unique_ptr<Accel> make_dyn_accel(const BuilderSpec&, const exec::serial&, const Backend&);
#if defined(_OPENMP)
extern template std::unique_ptr<Accel> make_dyn_accel(const BuilderSpec&, const exec::omp&, const Backend&);
#endif
#if defined(DYNBVH_WITH_TBB)
extern template std::unique_ptr<Accel> make_dyn_accel(const BuilderSpec&, const exec::tbb&, const Backend&);
#endif

} // namespace dynbvh::study
