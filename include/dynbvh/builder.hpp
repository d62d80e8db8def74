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
///  - `name`: the study's name of the builder.
#pragma once

#include <span>

#include "binned_sah.hpp"
#include "bvh.hpp"
#include "detail/emit.hpp"
#include "detail/references.hpp"
#include "lbvh.hpp"
#include "ploc.hpp"

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
};

} // namespace dynbvh::builder
