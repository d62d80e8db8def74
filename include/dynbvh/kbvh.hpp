// SPDX-License-Identifier: MIT
/// @file kbvh.hpp
/// KBVH: presplitting (presplit.hpp, Karras & Aila 2013) followed by a builder over the fragments,
/// PLOC by default. Large, badly fitting triangles become several tightly boxed references, which
/// mostly pays off on scenes with big diagonal triangles next to small ones (architecture, breaking
/// objects). Costs the split pass plus a build over (1 + beta) times the references; a leaf holding
/// two fragments of one triangle tests it once.
///
/// One line, PLOC underneath:
///     auto bvh = dynbvh::kbvh::build(tris, {.split = {.beta = 0.05f}}, dynbvh::exec::omp{});
/// LBVH (or binned SAH) underneath: name the builder in the Config's type,
///     dynbvh::kbvh::Config<dynbvh::kbvh::with_lbvh> cfg{.split = {.beta = 0.1f}, .builder = {.morton_bits = 63}};
///     auto bvh = dynbvh::kbvh::build(tris, cfg, dynbvh::exec::omp{});
/// or spell it: dynbvh::kbvh::build<dynbvh::Node<>, dynbvh::prim::indexed, dynbvh::kbvh::with_lbvh>(tris).
#pragma once

#include <span>
#include <vector>
#include <utility>

#include "binned_sah.hpp"
#include "bvh.hpp"
#include "detail/emit.hpp"
#include "detail/emit_wide.hpp"
#include "executor.hpp"
#include "lbvh.hpp"
#include "mesh.hpp"
#include "ploc.hpp"
#include "presplit.hpp"
#include "detail/references.hpp"
#include "detail/triangle_source.hpp"

namespace dynbvh::kbvh {

/// Builder policies: which builder runs over the fragments. A policy names its Config and
/// forwards to that builder's build_tree (which may reorder the references).
struct with_ploc {
    /// The builder's Config (kbvh::Config::builder).
    using config = ploc::Config;
    /// The builder's raw tree over the fragments (may reorder `refs`).
    template <class T, class Exec>
    static BinaryTree build_tree(References<T>& refs, const config& cfg, const Exec& ex) { return ploc::build_tree(refs, cfg, ex); }
};
/// LBVH over the fragments (lbvh.hpp): the fastest build.
struct with_lbvh {
    /// The builder's Config (kbvh::Config::builder).
    using config = lbvh::Config;
    /// The builder's raw tree over the fragments (may reorder `refs`).
    template <class T, class Exec>
    static BinaryTree build_tree(References<T>& refs, const config& cfg, const Exec& ex) { return lbvh::build_tree(refs, cfg, ex); }
};
/// Binned SAH over the fragments (binned_sah.hpp): the best tree, the slowest build.
struct with_binned_sah {
    /// The builder's Config (kbvh::Config::builder).
    using config = binned_sah::Config;
    /// The builder's raw tree over the fragments (may reorder `refs`).
    template <class T, class Exec>
    static BinaryTree build_tree(References<T>& refs, const config& cfg, const Exec& ex) { return binned_sah::build_tree(refs, cfg, ex); }
};

/// KBVH knobs: the split budget and the chosen builder's own Config (its `leaves` field sets the
/// leaf collapse). `{.split = {.beta = 0.1f}, .builder = {.radius = 10}}`.
template <class Builder = with_ploc>
struct Config {
    presplit::Config split{};             ///< presplit budget (beta, default 0.05 as in the study)
    typename Builder::config builder{};   ///< knobs of the builder over the fragments, leaf collapse included
};

/// Presplit fragments of `tris` (a std::span<const Triangle<T>> or a MeshView, mesh.hpp) and the builder's
/// raw tree over them (tree leaves index the returned references, whose `prim` names the user's triangle).
/// For users who emit their own layout.
template <class Builder = with_ploc, dynbvh::detail::triangle_source Source, class Exec>
std::pair<References<dynbvh::detail::source_scalar_t<Source>>, BinaryTree> build_tree(Source tris, const Config<Builder>& cfg,
                                                                                     const Exec& ex) {
    auto refs = make_references(tris, ex);
    if (presplit::budget(refs.size(), cfg.split) > 0) refs = presplit::split(refs, tris, cfg.split, ex);
    auto tree = Builder::build_tree(refs, cfg.builder, ex);
    return {std::move(refs), std::move(tree)};
}

/// Builds a KBVH over `tris` (see the file comment). Triangles with non-finite vertices are left out
/// (counted in Bvh::excluded); `tris` is not modified. A split triangle may appear in several leaves
/// of the result, at most once per leaf. Throws what presplit::split and the builder throw.
/// @tparam Builder with_ploc (default), with_lbvh or with_binned_sah; deduced from a named Config.
template <class NodeT = Node<>, class Prim = prim::indexed, class Builder = with_ploc, class Exec = exec::default_executor>
Bvh<NodeT, Prim> build(std::span<const Triangle<typename NodeT::scalar_type>> tris, const Config<Builder>& cfg = {},
                       const Exec& ex = {}) {
    auto [refs, tree] = build_tree<Builder>(tris, cfg, ex);
    return emit_bvh<NodeT, Prim>(tree, refs, tris, cfg.builder.leaves, ex);
}

/// Builds a KBVH over an indexed mesh read in place (mesh.hpp): the tree `build` gives over
/// `make_triangles(vertices, indices)`, bit for bit, without that copy. NodeT defaults to Node<T>.
template <class NodeT = void, class Prim = prim::indexed, class Builder = with_ploc, class Exec = exec::default_executor, class T,
          class Index>
Bvh<dynbvh::detail::node_for_t<NodeT, T>, Prim> build(const MeshView<T, Index>& mesh, const Config<Builder>& cfg = {},
                                                      const Exec& ex = {}) {
    auto [refs, tree] = build_tree<Builder>(mesh, cfg, ex);
    return emit_bvh<dynbvh::detail::node_for_t<NodeT, T>, Prim>(tree, refs, mesh, cfg.builder.leaves, ex);
}

/// Builds a KBVH straight into the W-wide layout (W = 4 or 8; detail/emit_wide.hpp): the tree
/// `make_wide<W>(build<NodeT, Prim, Builder>(tris, cfg, ex), ex)` gives, bit for bit, without the binary nodes.
template <int W = 8, class NodeT = Node<>, class Prim = prim::indexed, class Builder = with_ploc, class Exec = exec::default_executor>
wide_bvh_of<Bvh<NodeT, Prim>, W> build_wide(std::span<const Triangle<typename NodeT::scalar_type>> tris,
                                            const Config<Builder>& cfg = {}, const Exec& ex = {}) {
    auto [refs, tree] = build_tree<Builder>(tris, cfg, ex);
    return emit_wide_bvh<W, NodeT, Prim>(tree, refs, tris, cfg.builder.leaves, ex);
}

/// build_wide over an indexed mesh read in place (mesh.hpp); same tree as over make_triangles' array.
template <int W = 8, class NodeT = void, class Prim = prim::indexed, class Builder = with_ploc,
          class Exec = exec::default_executor, class T, class Index>
wide_bvh_of<Bvh<dynbvh::detail::node_for_t<NodeT, T>, Prim>, W> build_wide(const MeshView<T, Index>& mesh,
                                                                         const Config<Builder>& cfg = {}, const Exec& ex = {}) {
    auto [refs, tree] = build_tree<Builder>(mesh, cfg, ex);
    return emit_wide_bvh<W, dynbvh::detail::node_for_t<NodeT, T>, Prim>(tree, refs, mesh, cfg.builder.leaves, ex);
}

/// The same for a std::vector of triangles of any scalar, the node type following the triangles:
/// `dynbvh::kbvh::build(std::vector<Triangled>{...})` is a Bvh<Node<double>>.
template <int = 0, class T, class Builder = with_ploc, class Exec = exec::default_executor>
Bvh<Node<T>> build(const std::vector<Triangle<T>>& tris, const Config<Builder>& cfg = {}, const Exec& ex = {}) {
    return build<Node<T>, prim::indexed, Builder, Exec>(std::span<const Triangle<T>>(tris), cfg, ex);
}

} // namespace dynbvh::kbvh
