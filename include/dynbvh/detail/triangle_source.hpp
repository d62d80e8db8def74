// SPDX-License-Identifier: MIT
/// @file detail/triangle_source.hpp
/// The one notion of input the internal steps (references, presplit, copied leaves, block packing,
/// refit, leaf tests) are written against: a "triangle source", something small and trivially copyable
/// with size() and operator[](i) giving triangle i (a `const Triangle<T>&` or a Triangle<T> by value).
/// std::span<const Triangle<T>> and MeshView (mesh.hpp) are the two the public API passes; both go
/// through the same code, so a mesh gives the span's results bit for bit.
#pragma once

#include <concepts>
#include <cstddef>
#include <span>
#include <type_traits>
#include <utility>

#include "../node.hpp"
#include "../triangle.hpp"

namespace dynbvh::detail {

template <class>
struct triangle_scalar;
template <class T>
struct triangle_scalar<Triangle<T>> {
    using type = T;
};

/// The triangle type `S::operator[]` gives, without reference or const.
template <class S>
using source_triangle_t = std::remove_cvref_t<decltype(std::declval<const S&>()[std::size_t(0)])>;

/// A triangle source (see the file comment). Passed by value: a span or a MeshView, a few words.
template <class S>
concept triangle_source = std::is_trivially_copyable_v<S> && requires(const S& s, std::size_t i) {
    { s.size() } -> std::convertible_to<std::size_t>;
    typename triangle_scalar<source_triangle_t<S>>::type;
};

/// The scalar of source S's triangles.
template <class S>
using source_scalar_t = typename triangle_scalar<source_triangle_t<S>>::type;

/// What the leaf loops index: for a span its raw pointer (so the span path compiles as before), for any
/// other source the source itself.
template <class S>
auto leaf_reader(const S& tris) noexcept {
    if constexpr (std::is_same_v<S, std::span<const source_triangle_t<S>>>) return tris.data();
    else return tris;
}

/// What a tree's leaf loops read triangle slots from: its own copies (prim::copied, indexed by slot),
/// else leaf_reader(tris) (indexed by prim_ids[slot]).
template <class Tree, class S>
auto leaf_triangles_of(const Tree& tree, const S& tris) noexcept {
    if constexpr (Tree::precomputed) return tree.leaf_triangles.data();
    else return leaf_reader(tris);
}

/// The node type of a mesh overload (`build<NodeT>(mesh)`): NodeT, or Node<T> when NodeT is void (the
/// default there, so that a double mesh builds a Node<double> tree as a std::vector of Triangled does).
template <class NodeT, class T>
struct node_for {
    static_assert(std::is_same_v<typename NodeT::scalar_type, T>, "dynbvh: the node's scalar differs from the mesh's");
    using type = NodeT;
};
template <class T>
struct node_for<void, T> {
    using type = Node<T>;
};
/// See node_for.
template <class NodeT, class T>
using node_for_t = typename node_for<NodeT, T>::type;

} // namespace dynbvh::detail
