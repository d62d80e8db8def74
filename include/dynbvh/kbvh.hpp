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
#include "detail/scratch.hpp"
#include "detail/triangle_source.hpp"
#include "wide_blocks.hpp"

namespace dynbvh::kbvh {

/// Builder policies: which builder runs over the fragments. A policy names its Config and
/// forwards to that builder's build_tree (which may reorder the references).
struct with_ploc {
    /// The builder's Config (kbvh::Config::builder).
    using config = ploc::Config;
    /// The builder's raw tree over the fragments (may reorder `refs`).
    template <class T, class Exec>
    static BinaryTree build_tree(References<T>& refs, const config& cfg, const Exec& ex) { return ploc::build_tree(refs, cfg, ex); }
    /// build_tree with the facts of every inner node made as the clusters merge (the emission then
    /// skips its bottom-up pass; the same facts, bit for bit).
    template <class T, class Exec>
    static BinaryTree build_tree_with_info(References<T>& refs, const config& cfg,
                                           scratch_vector<dynbvh::detail::RawNodeInfo<T>>& info, const Exec& ex) {
        return ploc::detail::build_tree_with_info(refs, cfg, info, ex);
    }
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

namespace detail {

/// The whole-build step for dynbvh::detail::build_over (detail/emit_wide.hpp), which emits the tree
/// binary or W-wide (with prim::blocks<L>, blocks packed during the emission): references, fragments,
/// the builder's tree and the facts of its inner nodes (a builder that makes them as it goes, PLOC,
/// skips compute_node_info's bottom-up pass).
template <class Builder>
struct Topology {
    static constexpr bool from_triangles = true;
    template <class Source, class Exec>
    auto operator()(Source tris, const Config<Builder>& cfg,
                    scratch_vector<dynbvh::detail::RawNodeInfo<dynbvh::detail::source_scalar_t<Source>>>& info, const Exec& ex) const {
        auto refs = make_references(tris, ex);
        if (presplit::budget(refs.size(), cfg.split) > 0) refs = presplit::split(refs, tris, cfg.split, ex);
        BinaryTree tree;
        if constexpr (requires { Builder::build_tree_with_info(refs, cfg.builder, info, ex); }) {
            tree = Builder::build_tree_with_info(refs, cfg.builder, info, ex);
        } else {
            tree = Builder::build_tree(refs, cfg.builder, ex);
            info.resize(refs.size() == 0 ? 0 : tree.inner_count());
            if (refs.size() != 0) dynbvh::detail::compute_node_info(tree, refs, cfg.builder.leaves, std::span(info.data(), info.size()), ex);
        }
        return std::pair{std::move(refs), std::move(tree)};
    }
};

/// kbvh's whole build through the shared build_over: one code path for every input and layout.
template <int W, class NodeT, class Prim, class Builder, class Source, class Exec>
auto build_over(Source tris, const Config<Builder>& cfg, const Exec& ex) {
    return dynbvh::detail::build_over<W, NodeT, Prim>(tris, cfg, Topology<Builder>{}, ex);
}

} // namespace detail

/// Builds a KBVH over `tris` (see the file comment). Triangles with non-finite vertices are left out
/// (counted in Bvh::excluded); `tris` is not modified. A split triangle may appear in several leaves
/// of the result, at most once per leaf. Throws what presplit::split and the builder throw.
/// @tparam Builder with_ploc (default), with_lbvh or with_binned_sah; deduced from a named Config.
template <class NodeT = Node<>, class Prim = prim::indexed, class Builder = with_ploc, class Exec = exec::default_executor>
Bvh<NodeT, Prim> build(std::span<const Triangle<typename NodeT::scalar_type>> tris, const Config<Builder>& cfg = {},
                       const Exec& ex = {}) {
    return detail::build_over<0, NodeT, Prim>(tris, cfg, ex);
}

/// Builds a KBVH over an indexed mesh read in place (mesh.hpp): the tree `build` gives over
/// `make_triangles(vertices, indices)`, bit for bit, without that copy. NodeT defaults to Node<T>.
template <class NodeT = void, class Prim = prim::indexed, class Builder = with_ploc, class Exec = exec::default_executor, class T,
          class Index>
Bvh<dynbvh::detail::node_for_t<NodeT, T>, Prim> build(const MeshView<T, Index>& mesh, const Config<Builder>& cfg = {},
                                                      const Exec& ex = {}) {
    return detail::build_over<0, dynbvh::detail::node_for_t<NodeT, T>, Prim>(mesh, cfg, ex);
}

/// Builds a KBVH straight into the W-wide layout (W = 4 or 8; detail/emit_wide.hpp): the tree
/// `make_wide<W>(build<NodeT, Prim, Builder>(tris, cfg, ex), ex)` gives, bit for bit, without the binary nodes.
template <int W = 8, class NodeT = Node<>, class Prim = prim::indexed, class Builder = with_ploc, class Exec = exec::default_executor>
wide_bvh_of<Bvh<NodeT, Prim>, W> build_wide(std::span<const Triangle<typename NodeT::scalar_type>> tris,
                                            const Config<Builder>& cfg = {}, const Exec& ex = {}) {
    return detail::build_over<W, NodeT, Prim>(tris, cfg, ex);
}

/// build_wide over an indexed mesh read in place (mesh.hpp); same tree as over make_triangles' array.
template <int W = 8, class NodeT = void, class Prim = prim::indexed, class Builder = with_ploc,
          class Exec = exec::default_executor, class T, class Index>
wide_bvh_of<Bvh<dynbvh::detail::node_for_t<NodeT, T>, Prim>, W> build_wide(const MeshView<T, Index>& mesh,
                                                                         const Config<Builder>& cfg = {}, const Exec& ex = {}) {
    return detail::build_over<W, dynbvh::detail::node_for_t<NodeT, T>, Prim>(mesh, cfg, ex);
}

/// The traced layout in one step: the W-wide tree `build_wide<W>(tris, cfg, ex)` gives with its leaves
/// packed into SIMD blocks of L triangles (wide_blocks.hpp), the tree
/// `make_wide_blocks<L>(build_wide<W>(tris, cfg, ex), tris, ex)` gives, bit for bit (a leaf with two
/// fragments of one triangle packs it once). Pass `.builder = {.leaves = dynbvh::block_leaves}` for
/// leaves sized for blocks of 8. One line:
/// `auto t = dynbvh::kbvh::build_blocks(tris, {.builder = {.leaves = dynbvh::block_leaves}}, ex);`
template <int W = 8, int L = W, class Builder = with_ploc, class Exec = exec::default_executor>
WideBvh<WideNode<float, std::uint32_t, W>, prim::blocks<L>> build_blocks(std::span<const Triangle<float>> tris,
                                                                         const Config<Builder>& cfg = {}, const Exec& ex = {}) {
    return detail::build_over<W, Node<float>, prim::blocks<L>>(tris, cfg, ex);
}

/// build_blocks over an indexed float mesh read in place (mesh.hpp): the span's tree, bit for bit.
template <int W = 8, int L = W, class Builder = with_ploc, class Exec = exec::default_executor, class Index>
WideBvh<WideNode<float, std::uint32_t, W>, prim::blocks<L>> build_blocks(const MeshView<float, Index>& mesh,
                                                                         const Config<Builder>& cfg = {}, const Exec& ex = {}) {
    return detail::build_over<W, Node<float>, prim::blocks<L>>(mesh, cfg, ex);
}

/// The same for a std::vector of triangles of any scalar, the node type following the triangles:
/// `dynbvh::kbvh::build(std::vector<Triangled>{...})` is a Bvh<Node<double>>.
template <int = 0, class T, class Builder = with_ploc, class Exec = exec::default_executor>
Bvh<Node<T>> build(const std::vector<Triangle<T>>& tris, const Config<Builder>& cfg = {}, const Exec& ex = {}) {
    return build<Node<T>, prim::indexed, Builder, Exec>(std::span<const Triangle<T>>(tris), cfg, ex);
}

} // namespace dynbvh::kbvh
