// SPDX-License-Identifier: MIT
/// @file mesh.hpp
/// An indexed triangle mesh read in place, like Embree's geometry buffers: a vertex buffer with a
/// stride (positions interleaved with other attributes are fine) and an index buffer of 16- or 32-bit
/// triangles. Every builder (morton_wide included), refit (binary, wide, block trees), traversal,
/// make_wide_blocks and Dynamic::update accept a MeshView wherever they accept a
/// `std::span<const Triangle<T>>`, with the same results bit for bit as over
/// `make_triangles(vertices, indices)`, and without that flattening copy (TwoLevel objects, validate
/// and epo still take spans):
/// @code
///   const dynbvh::MeshView<float> mesh(vertices, indices);   // std::span<const Vec3f>, std::span<const std::uint32_t>
///   auto bvh = dynbvh::ploc::build(mesh);                    // the tree make_triangles' array would give
/// @endcode
/// The buffers stay the user's: the view holds pointers only and never writes. The indices are checked
/// once, when the view is made; the vertices may then move in place from frame to frame (refit or
/// Dynamic::update with the same view). Change the indices only by making a new view.
#pragma once

#include <cstddef>
#include <cstdint>
#include <cstring>
#include <limits>
#include <span>
#include <stdexcept>
#include <string>
#include <type_traits>

#include "triangle.hpp"
#include "vec.hpp"

namespace dynbvh {

/// A user's indexed triangle mesh, read in place: vertex i is the 3 T (x, y, z) at
/// `(const std::byte*)vertices + i * stride`, triangle k is vertices indices[3k], indices[3k + 1],
/// indices[3k + 2] (their order sets the normal, as for Triangle). 40 bytes; copy it freely.
/// @tparam T      the coordinates' type (float or double), the trees' scalar
/// @tparam Index  std::uint32_t (default) or std::uint16_t
template <class T, class Index = std::uint32_t>
class MeshView {
    static_assert(std::is_same_v<Index, std::uint32_t> || std::is_same_v<Index, std::uint16_t>,
                  "dynbvh::MeshView: Index is std::uint32_t or std::uint16_t");
    static_assert(std::is_floating_point_v<T>, "dynbvh::MeshView: T is float or double");

public:
    /// The coordinates' type.
    using scalar_type = T;
    /// The index buffer's element type.
    using index_type = Index;
    /// What operator[] returns.
    using triangle_type = Triangle<T>;

    /// An empty mesh (no vertex, no triangle).
    constexpr MeshView() noexcept = default;

    /// A mesh over tightly packed vertices (stride sizeof(Vec3<T>)) and `indices` (3 per triangle).
    /// Throws std::invalid_argument as the strided constructor does. O(indices).
    MeshView(std::span<const Vec3<T>> vertices, std::span<const Index> indices)
        : MeshView(vertices.data(), vertices.size(), sizeof(Vec3<T>), indices.data(), indices.size()) {}

    /// A mesh over `vertex_count` vertices `stride` bytes apart from `vertices` (each 3 T: x, y, z,
    /// then whatever else the user stores) and `indices` (3 per triangle).
    /// Throws std::invalid_argument naming the argument when `vertices` is null with vertex_count > 0,
    /// `stride` < 3 * sizeof(T) or not a multiple of alignof(T), `vertices` is not aligned to alignof(T),
    /// `vertex_count * stride` overflows, `indices` is null with index_count > 0, index_count is not a
    /// multiple of 3, or an index is >= vertex_count ("mesh indices: triangle 17 has vertex index 1000
    /// >= vertex count 800"). The buffer must hold (vertex_count - 1) * stride + 3 * sizeof(T) bytes.
    /// O(indices): one pass for the largest index.
    MeshView(const void* vertices, std::size_t vertex_count, std::size_t stride, const Index* indices, std::size_t index_count)
        : vertices_(static_cast<const std::byte*>(vertices)), vertex_count_(vertex_count), stride_(stride),
          indices_(indices), triangle_count_(index_count / 3) {
        check(index_count);
    }

    /// The same with the indices as a span.
    MeshView(const void* vertices, std::size_t vertex_count, std::size_t stride, std::span<const Index> indices)
        : MeshView(vertices, vertex_count, stride, indices.data(), indices.size()) {}

    /// Number of triangles (index count / 3).
    constexpr std::size_t size() const noexcept { return triangle_count_; }
    /// True when there is no triangle.
    constexpr bool empty() const noexcept { return triangle_count_ == 0; }
    /// Number of vertices.
    constexpr std::size_t vertex_count() const noexcept { return vertex_count_; }
    /// Bytes from one vertex to the next.
    constexpr std::size_t stride() const noexcept { return stride_; }
    /// The index buffer (3 * size() entries).
    constexpr std::span<const Index> indices() const noexcept { return {indices_, 3 * triangle_count_}; }

    /// Vertex `i` (i < vertex_count(), unchecked). O(1).
    Vec3<T> vertex(std::size_t i) const noexcept {
        const std::byte* p = vertices_ + i * stride_;
        Vec3<T> v;
        // (memcpy: the buffer is the user's, of any struct type; compilers emit plain loads)
        std::memcpy(&v.x, p, sizeof(T));
        std::memcpy(&v.y, p + sizeof(T), sizeof(T));
        std::memcpy(&v.z, p + 2 * sizeof(T), sizeof(T));
        return v;
    }

    /// Triangle `k` (k < size(), unchecked), by value: what make_triangles would store at k. O(1).
    Triangle<T> operator[](std::size_t k) const noexcept {
        const Index* t = indices_ + 3 * k;
        return {vertex(t[0]), vertex(t[1]), vertex(t[2])};
    }

private:
    void check(std::size_t index_count) const {
        const auto fail = [](const std::string& what) { throw std::invalid_argument("dynbvh::MeshView: " + what); };
        if (vertices_ == nullptr && vertex_count_ != 0)
            fail("vertices is null but vertex_count is " + std::to_string(vertex_count_));
        if (stride_ < 3 * sizeof(T))
            fail("stride " + std::to_string(stride_) + " bytes is less than one vertex (3 * sizeof(T) = " +
                 std::to_string(3 * sizeof(T)) + " bytes)");
        if (stride_ % alignof(T) != 0)
            fail("stride " + std::to_string(stride_) + " bytes is not a multiple of alignof(T) = " + std::to_string(alignof(T)));
        if (reinterpret_cast<std::uintptr_t>(vertices_) % alignof(T) != 0)
            fail("vertices is not aligned to alignof(T) = " + std::to_string(alignof(T)) + " bytes");
        if (vertex_count_ != 0 && stride_ > std::numeric_limits<std::size_t>::max() / vertex_count_)
            fail("vertex_count " + std::to_string(vertex_count_) + " * stride " + std::to_string(stride_) + " overflows");
        if (indices_ == nullptr && index_count != 0) fail("indices is null but the index count is " + std::to_string(index_count));
        if (index_count % 3 != 0) fail("index count " + std::to_string(index_count) + " is not a multiple of 3");
        // The largest index in one pass (vectorisable), the culprit only when there is one.
        Index hi = 0;
        for (std::size_t i = 0; i < index_count; ++i) hi = indices_[i] > hi ? indices_[i] : hi;
        if (index_count == 0 || std::size_t(hi) < vertex_count_) return;
        for (std::size_t i = 0;; ++i)
            if (std::size_t(indices_[i]) >= vertex_count_)
                fail("mesh indices: triangle " + std::to_string(i / 3) + " has vertex index " + std::to_string(indices_[i]) +
                     " >= vertex count " + std::to_string(vertex_count_));
    }

    const std::byte* vertices_ = nullptr;
    std::size_t vertex_count_ = 0;
    std::size_t stride_ = sizeof(Vec3<T>);
    const Index* indices_ = nullptr;
    std::size_t triangle_count_ = 0;
};

/// The view's scalar from its vertex span: `dynbvh::MeshView mesh(vertices, indices);`.
template <class T, class Index>
MeshView(std::span<const Vec3<T>>, std::span<const Index>) -> MeshView<T, Index>;

} // namespace dynbvh
