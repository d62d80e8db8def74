// SPDX-License-Identifier: MIT
/// @file builder.hpp
/// Builder policies: one type per builder, so that code holding trees over time (the refit-or-rebuild
/// policy `Dynamic`, dynamic.hpp; the two-level scene `TwoLevel`, two_level.hpp) takes the builder as a
/// template parameter. Each policy offers
///  - `config`: the builder's plain Config struct,
///  - `build<NodeT, Prim>(tris, cfg, ex)`: a whole tree over triangles (the builder's own `build`; `tris`
///    is what that takes: a std::span or std::vector of triangles, or a MeshView, mesh.hpp),
///  - `build_tree(refs, cfg, ex)`: the raw topology over prepared references (boxes of anything: the
///    top level of a two-level scene builds over one box per instance),
///  - `build_blocks<W, L>(tris, cfg, ex)`: the traced layout, the W-wide float tree with its leaves in
///    SIMD blocks of L triangles (wide_blocks.hpp), for `tris` a span, vector or MeshView of float
///    triangles: the tree make_wide_blocks<W, L>(build(tris, cfg, ex), tris, ex) gives, bit for bit
///    (PLOC emits it directly, the others convert their wide tree),
///  - `name`: the study's name of the builder.
#pragma once

#include <span>

#include "binned_sah.hpp"
#include "bvh.hpp"
#include "detail/emit.hpp"
#include "detail/references.hpp"
#include "lbvh.hpp"
#include "ploc.hpp"
#include "wide_blocks.hpp"

namespace dynbvh::builder {

/// PLOC (Meister & Bittner 2018), ploc.hpp: the default of every policy taking a builder.
struct ploc {
    using config = dynbvh::ploc::Config;   ///< the builder's knobs
    static constexpr const char* name = "ploc";   ///< the study\'s name
    /// dynbvh::ploc::build. O(n log n) work, parallel over `ex`.
    template <class NodeT, class Prim, class Exec, class Tris>
    static Bvh<NodeT, Prim> build(const Tris& tris, const config& cfg, const Exec& ex) {
        return dynbvh::ploc::build<NodeT, Prim, Exec>(tris, cfg, ex);
    }
    /// dynbvh::ploc::build_tree (reorders `refs` along the Morton curve).
    template <class T, class Exec>
    static BinaryTree build_tree(References<T>& refs, const config& cfg, const Exec& ex) {
        return dynbvh::ploc::build_tree(refs, cfg, ex);
    }
    /// dynbvh::ploc::build_blocks: the traced layout emitted directly. O(n log n), parallel over `ex`.
    template <int W, int L, class Exec, class Tris>
    static WideBvh<WideNode<float, std::uint32_t, W>, prim::blocks<L>> build_blocks(const Tris& tris, const config& cfg, const Exec& ex) {
        return dynbvh::ploc::build_blocks<W, L>(tris, cfg, ex);
    }
};

/// LBVH (Karras 2012, Apetrei 2014), lbvh.hpp: fastest build, lowest quality.
struct lbvh {
    using config = dynbvh::lbvh::Config;   ///< the builder's knobs
    static constexpr const char* name = "lbvh";   ///< the study\'s name
    /// dynbvh::lbvh::build. O(n) work per step, parallel over `ex`.
    template <class NodeT, class Prim, class Exec, class Tris>
    static Bvh<NodeT, Prim> build(const Tris& tris, const config& cfg, const Exec& ex) {
        return dynbvh::lbvh::build<NodeT, Prim, Exec>(tris, cfg, ex);
    }
    /// dynbvh::lbvh::build_tree (reorders `refs` along the Morton curve).
    template <class T, class Exec>
    static BinaryTree build_tree(References<T>& refs, const config& cfg, const Exec& ex) {
        return dynbvh::lbvh::build_tree(refs, cfg, ex);
    }
    /// make_wide_blocks<L> of dynbvh::lbvh::build_wide<W>: the traced layout.
    template <int W, int L, class Exec, class Tris>
    static WideBvh<WideNode<float, std::uint32_t, W>, prim::blocks<L>> build_blocks(const Tris& tris, const config& cfg, const Exec& ex) {
        return make_wide_blocks<L>(dynbvh::lbvh::build_wide<W, Node<float>, prim::indexed>(tris, cfg, ex), tris, ex);
    }
};

/// Binned SAH (Wald 2007), binned_sah.hpp: slowest build, best quality.
struct binned_sah {
    using config = dynbvh::binned_sah::Config;   ///< the builder's knobs
    static constexpr const char* name = "binned-sah";   ///< the study\'s name
    /// dynbvh::binned_sah::build. O(n log n) work, parallel over `ex`.
    template <class NodeT, class Prim, class Exec, class Tris>
    static Bvh<NodeT, Prim> build(const Tris& tris, const config& cfg, const Exec& ex) {
        return dynbvh::binned_sah::build<NodeT, Prim, Exec>(tris, cfg, ex);
    }
    /// dynbvh::binned_sah::build_tree (`refs` unchanged).
    template <class T, class Exec>
    static BinaryTree build_tree(References<T>& refs, const config& cfg, const Exec& ex) {
        return dynbvh::binned_sah::build_tree(refs, cfg, ex);
    }
    /// make_wide_blocks<L> of dynbvh::binned_sah::build_wide<W>: the traced layout.
    template <int W, int L, class Exec, class Tris>
    static WideBvh<WideNode<float, std::uint32_t, W>, prim::blocks<L>> build_blocks(const Tris& tris, const config& cfg, const Exec& ex) {
        return make_wide_blocks<L>(dynbvh::binned_sah::build_wide<W, Node<float>, prim::indexed>(tris, cfg, ex), tris, ex);
    }
};

} // namespace dynbvh::builder
