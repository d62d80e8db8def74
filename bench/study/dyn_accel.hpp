// DynAccel: the study's Accel over our builders (lbvh, kbvh, ploc, binned-sah, refit) on one executor,
// and the tile loop every Accel traces with. The builders are instantiated once per executor in
// accel_<executor>.cpp (three files that compile in parallel), the traversals once per primitive
// policy in accel_trace.cpp.
#pragma once

#include <memory>
#include <span>
#include <stdexcept>
#include <type_traits>

#include <dynbvh/binned_sah.hpp>
#include <dynbvh/bvh.hpp>
#include <dynbvh/kbvh.hpp>
#include <dynbvh/lbvh.hpp>
#include <dynbvh/morton_wide.hpp>
#include <dynbvh/packet.hpp>
#include <dynbvh/ploc.hpp>
#include <dynbvh/refit.hpp>
#include <dynbvh/sah.hpp>
#include <dynbvh/traverse.hpp>
#include <dynbvh/wide.hpp>
#include <dynbvh/wide_blocks.hpp>

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

/// The same loop with the rays of each tile in packets of N = 32 (8x4 pixels), 16 (4x4) or 8 (4x2):
/// `isect(rays, valid, prims)` traces a packet (valid[k] == 0 for a lane past the tile's edge, whose
/// ray is a copy of lane 0's) and writes the hit triangles of its valid lanes.
template <int N, class Intersect>
void trace_tiles_packets(const Backend& backend, const RayGen& gen, std::span<std::uint32_t> out, const Intersect& isect) {
    const auto w = std::size_t(gen.width());
    backend.for_tasks(gen.tile_count(), [&](std::size_t k) {
        for_each_packet<N>(gen, gen.tile(k), [&](const Rayf* rays, const int* valid, int x0, int y0) {
            std::uint32_t prims[N];
            isect(rays, valid, prims);
            for (int j = 0; j < N; ++j)
                if (valid[j]) out[std::size_t(y0 + packet_dy(j)) * w + std::size_t(x0 + packet_dx(j))] = prims[j];
        });
    });
}

/// Rays per packet of the study's primary rays through our packet traversal (wide trees and two-level
/// scenes): 32 = 8x4 pixels as two 4x4 halves (for_each_packet), the fastest on coherent rays.
inline constexpr int primary_packet_rays = 32;

/// trace_tiles_packets<N> with each packet as a RayPacket<float, N>: `isect(packet, active, prims)`
/// (active: the mask of the lanes inside the tile) writes the hit triangles of the active lanes.
template <int N, class Intersect>
void trace_tiles_ray_packets(const Backend& backend, const RayGen& gen, std::span<std::uint32_t> out, const Intersect& isect) {
    trace_tiles_packets<N>(backend, gen, out, [&](const Rayf* rays, const int* valid, std::uint32_t* prims) {
        RayPacket<float, N> p;
        std::uint32_t active = 0;
        for (int k = 0; k < N; ++k) {
            p.set(k, rays[k]);
            active |= valid[k] ? std::uint32_t(1) << k : 0u;
        }
        isect(static_cast<const RayPacket<float, N>&>(p), active, prims);
    });
}

/// A DynAccel<Exec, prim::indexed or prim::copied> for `spec` (one of our builders).
template <class Exec>
std::unique_ptr<Accel> make_dyn_accel(const BuilderSpec& spec, const Exec& ex, const Backend& backend);

namespace accel_impl {

/// One frame's trees from one of our builders and the queries on them. Nothing here depends on the
/// executor, so the traversal code is compiled once per primitive policy (accel_trace.cpp) instead of
/// once per executor.
template <class Prim>
struct Trees {
    using BvhT = Bvh<Node<>, Prim>;
    BvhT bvh;                          ///< refit's tree (the SAH column reads it) and wide=0's traced one;
                                       ///< its leaf part moves to the wide tree when there is one
    wide_bvh_of<BvhT, 4> wide4;        ///< built when spec.wide == 4
    wide_bvh_of<BvhT, 8> wide8;        ///< built when spec.wide == 8
    wide_blocks_bvh_of<BvhT, 4> blocks4;   ///< built instead of wide4 when spec.blocks (wide_blocks.hpp)
    wide_blocks_bvh_of<BvhT, 8> blocks8;   ///< built instead of wide8 when spec.blocks
    /// When set, traced instead of blocks4 / blocks8: a block tree held elsewhere (auto's policy holds
    /// the traced tree itself, dynamic.hpp).
    const wide_blocks_bvh_of<BvhT, 4>* view4 = nullptr;
    const wide_blocks_bvh_of<BvhT, 8>* view8 = nullptr;

    /// One primary ray per pixel through the tree spec.wide names, with spec's box and triangle tests.
    void trace(const BuilderSpec& spec, const Backend& backend, std::span<const Trianglef> tris, const RayGen& gen,
               std::span<std::uint32_t> out) const;
    Hitf intersect(const BuilderSpec& spec, std::span<const Trianglef> tris, const Rayf& r) const;
    bool occluded(const BuilderSpec& spec, std::span<const Trianglef> tris, const Rayf& r) const;
    /// Up to 16 rays at once (the renderer's primary and shadow rays): packets (packet.hpp) on wide
    /// trees when spec.packets, else ray by ray; the answers of intersect / occluded either way.
    void intersect_packet(const BuilderSpec& spec, std::span<const Trianglef> tris, std::span<const Rayf> rays, std::span<Hitf> out) const;
    void occluded_packet(const BuilderSpec& spec, std::span<const Trianglef> tris, std::span<const Rayf> rays,
                         std::span<std::uint8_t> out) const;
    /// Bytes of the traced tree.
    std::size_t memory_bytes(const BuilderSpec& spec) const;
};
extern template struct Trees<prim::indexed>;
extern template struct Trees<prim::copied>;

/// The leaf collapse of our builders' binary trees for `spec`: its largest leaf, with block_leaves' costs
/// (fuller leaves) when the traced tree has SIMD triangle blocks. The per-frame rebuilds and auto's
/// policy both build with it.
inline LeafConfig leaf_config(const BuilderSpec& spec) {
    LeafConfig leaves{.max_leaf_size = spec.max_leaf};
    if (spec.blocks) leaves.cost = block_leaves.cost;   // fuller leaves for SIMD blocks
    return leaves;
}

/// Our builders on executor Exec with primitive policy Prim.
template <class Exec, class Prim>
class DynAccel final : public Accel {
public:
    DynAccel(const BuilderSpec& spec, const Exec& ex, const Backend& backend) : spec_(spec), ex_(ex), backend_(backend) {}

    void build(std::span<const Trianglef> tris) override {
        previous_ = std::move(current_);   // freed untimed in release_previous()
        sah_due_ = {};
        if (spec_.kind == Kind::morton_wide) {   // the traced tree only, no binary tree
            build_morton_wide(tris);
            return;
        }
        if (spec_.kind == Kind::refit && spec_.blocks && refit_blocks_in_place(tris)) return;
        if (spec_.kind != Kind::refit && spec_.wide != 0) {
            // The traced tree straight from the builder (no binary tree built and converted); sah()
            // builds the same tree's binary form, untimed, for the thesis's measure.
            if (spec_.wide == 4) build_traced<4>(tris, current_.wide4, current_.blocks4);
            if (spec_.wide == 8) build_traced<8>(tris, current_.wide8, current_.blocks8);
            sah_due_ = tris;   // (the runner keeps the frame's triangles alive until after sah())
            return;
        }
        build_binary(tris);
        // refit's first frame, and refit without blocks: the 4- or 8-wide tree converted from the
        // binary one it refits (timed as part of the build); with blocks its leaves are copied into
        // triangle blocks and the binary tree keeps its leaf part.
        if (spec_.blocks) {
            if (spec_.wide == 4) current_.blocks4 = make_wide_blocks<4>(current_.bvh, tris, ex_);
            if (spec_.wide == 8) current_.blocks8 = make_wide_blocks<8>(current_.bvh, tris, ex_);
            return;
        }
        if (spec_.wide == 4) current_.wide4 = take_wide<4>(current_.bvh);
        if (spec_.wide == 8) current_.wide8 = take_wide<8>(current_.bvh);
    }
    /// The traced W-wide tree built directly: with SIMD triangle blocks when spec_.blocks (ploc emits
    /// them, the others pack their wide tree's leaves), else with index leaves. Bit for bit the tree
    /// the binary build and make_wide(_blocks) give (the builders' own tests check it).
    template <int W>
    void build_traced(std::span<const Trianglef> tris, wide_bvh_of<typename Trees<Prim>::BvhT, W>& wide,
                      wide_blocks_bvh_of<typename Trees<Prim>::BvhT, W>& blocks) {
        if constexpr (std::is_same_v<Prim, prim::indexed>) {
            if (spec_.blocks && spec_.kind == Kind::ploc) {
                blocks = ploc::build_blocks<W>(tris, ploc_config(), ex_);
                return;
            }
            if (spec_.blocks && spec_.kind == Kind::kbvh) {
                blocks = kbvh::build_blocks<W>(tris, kbvh_config(), ex_);
                return;
            }
        }
        if (spec_.blocks) blocks = make_wide_blocks(build_fresh<W>(tris), tris, ex_);
        else wide = build_fresh<W>(tris);
    }
    /// A fresh tree from spec_.kind's builder (lbvh, ploc, kbvh or binned-sah): the binary Bvh for
    /// W = 0, else the builder's W-wide tree.
    template <int W>
    auto build_fresh(std::span<const Trianglef> tris) const {
        using NodeT = Node<>;
        const LeafConfig leaves = leaf_config(spec_);
        // (the wide builds are generic lambdas so that W = 0 never instantiates them)
        const auto pick = [&](auto binary, auto wide) {
            if constexpr (W == 0) return binary();
            else return wide(std::integral_constant<int, W>{});
        };
        switch (spec_.kind) {
            case Kind::lbvh: {
                const lbvh::Config cfg{.morton_bits = spec_.morton_bits, .leaves = leaves};
                return pick([&] { return lbvh::build<NodeT, Prim>(tris, cfg, ex_); },
                            [&](auto w) { return lbvh::build_wide<w(), NodeT, Prim>(tris, cfg, ex_); });
            }
            case Kind::ploc:
                return pick([&] { return ploc::build<NodeT, Prim>(tris, ploc_config(), ex_); },
                            [&](auto w) { return ploc::build_wide<w(), NodeT, Prim>(tris, ploc_config(), ex_); });
            case Kind::kbvh: {
                const kbvh::Config<kbvh::with_ploc> cfg = kbvh_config();
                return pick([&] { return kbvh::build<NodeT, Prim>(tris, cfg, ex_); },
                            [&](auto w) { return kbvh::build_wide<w(), NodeT, Prim>(tris, cfg, ex_); });
            }
            case Kind::binned_sah: {
                const binned_sah::Config cfg{.bins = spec_.bins, .leaves = leaves};
                return pick([&] { return binned_sah::build<NodeT, Prim>(tris, cfg, ex_); },
                            [&](auto w) { return binned_sah::build_wide<w(), NodeT, Prim>(tris, cfg, ex_); });
            }
            default:
                throw std::logic_error("DynAccel: not one of our builders");
        }
    }
    ploc::Config ploc_config() const {
        return {.radius = spec_.radius, .morton_bits = spec_.morton_bits, .leaves = leaf_config(spec_)};
    }
    kbvh::Config<kbvh::with_ploc> kbvh_config() const { return {.split = {.beta = spec_.beta}, .builder = ploc_config()}; }
    /// The wide tree over `bvh`'s leaf part, which it takes over (one copy of the references per frame);
    /// `bvh` keeps its nodes for the SAH column and gets the leaf part back before a refit.
    template <int W>
    wide_bvh_of<typename Trees<Prim>::BvhT, W> take_wide(typename Trees<Prim>::BvhT& bvh) {
        auto leaves = std::move(bvh.leaves());
        auto wide = make_wide<W>(bvh, ex_);   // copies an empty leaf part
        wide.leaves() = std::move(leaves);
        return wide;
    }
    /// refit with blocks after its first frame: the traced block tree refitted in place (wide_blocks.hpp:
    /// its blocks' vertices reloaded, its boxes recomputed; the topology kept), not the binary tree
    /// refitted and packed again. The binary tree, which only the SAH column reads, is refitted by
    /// release_previous(), outside the timed build. False (nothing done) at the first frame or a new
    /// triangle count.
    bool refit_blocks_in_place(std::span<const Trianglef> tris) {
        const auto take = [&](auto& now, auto& before) {
            if (before.empty() || before.primitive_count != tris.size()) return false;
            now = std::move(before);
            dynbvh::refit(now, tris, ex_);
            return true;
        };
        if (!(spec_.wide == 4 ? take(current_.blocks4, previous_.blocks4) : take(current_.blocks8, previous_.blocks8))) return false;
        current_.bvh = std::move(previous_.bvh);
        binary_due_ = tris;   // (the runner keeps the frame's triangles alive until after release_previous)
        return true;
    }
    void build_morton_wide(std::span<const Trianglef> tris) {
        const morton_wide::Config cfg{.morton_bits = spec_.morton_bits, .max_leaf_size = spec_.max_leaf};
        if (spec_.wide == 4) {
            auto w = morton_wide::build<4, Node<>, Prim>(tris, cfg, ex_);
            if (spec_.blocks) current_.blocks4 = make_wide_blocks(std::move(w), tris, ex_);
            else current_.wide4 = std::move(w);
        } else {
            auto w = morton_wide::build<8, Node<>, Prim>(tris, cfg, ex_);
            if (spec_.blocks) current_.blocks8 = make_wide_blocks(std::move(w), tris, ex_);
            else current_.wide8 = std::move(w);
        }
    }
    /// The binary tree: refit's (refitted, or built by its builder at the first frame or a new
    /// triangle count, as auto's), or a fresh one for the binary trace (wide=0).
    void build_binary(std::span<const Trianglef> tris) {
        auto& bvh = current_.bvh;
        if (spec_.kind != Kind::refit) {
            bvh = build_fresh<0>(tris);
            return;
        }
        if (!previous_.wide4.empty()) previous_.bvh.leaves() = std::move(previous_.wide4.leaves());
        if (!previous_.wide8.empty()) previous_.bvh.leaves() = std::move(previous_.wide8.leaves());
        if (!previous_.bvh.empty() && previous_.bvh.primitive_count == tris.size()) {
            bvh = std::move(previous_.bvh);
            dynbvh::refit(bvh, tris, ex_);
        } else if (spec_.over == Kind::lbvh) {
            bvh = lbvh::build<Node<>, Prim>(tris, {.morton_bits = spec_.morton_bits, .leaves = leaf_config(spec_)}, ex_);
        } else {
            bvh = ploc::build<Node<>, Prim>(tris, ploc_config(), ex_);
        }
    }
    void release_previous() override {
        previous_ = Trees<Prim>{};
        if (!binary_due_.empty()) dynbvh::refit(current_.bvh, binary_due_, ex_);   // the SAH column's tree (see refit_blocks_in_place)
        binary_due_ = {};
    }

    void trace(std::span<const Trianglef> tris, const RayGen& gen, std::span<std::uint32_t> out) override {
        current_.trace(spec_, backend_, tris, gen, out);
    }
    /// The binary tree's SAH (the thesis's measure); none for morton-wide, which builds no binary tree.
    /// For a tree built directly into the traced layout, that of the same tree's binary form, built here,
    /// outside the timed build and trace (the builders give the same tree either way).
    std::optional<double> sah() const override {
        if (spec_.kind == Kind::morton_wide) return std::nullopt;
        constexpr SahCost thesis{.ct = 3, .ci = 2};
        if (!sah_due_.empty()) return sah_cost(build_fresh<0>(sah_due_), thesis, ex_);
        return sah_cost(current_.bvh, thesis, ex_);
    }
    std::optional<std::size_t> memory_bytes() const override { return current_.memory_bytes(spec_); }
    /// Single-ray queries (effect rays) go through the same tree as trace().
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
    const Exec& ex_;
    const Backend& backend_;
    Trees<Prim> current_, previous_;
    std::span<const Trianglef> binary_due_;   // the frame whose triangles the binary tree still has to be refitted to
    std::span<const Trianglef> sah_due_;      // the frame whose traced tree was built directly (see sah())
};

} // namespace accel_impl

template <class Exec>
std::unique_ptr<Accel> make_dyn_accel(const BuilderSpec& spec, const Exec& ex, const Backend& backend) {
    if (spec.precomputed) return std::make_unique<accel_impl::DynAccel<Exec, prim::copied>>(spec, ex, backend);
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
