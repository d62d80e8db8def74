// SPDX-License-Identifier: MIT
/// @file detail/morton.hpp
/// Morton (Z-order) codes of reference centres, shared by LBVH, PLOC and presplitting.
/// Centres are quantised on a 2^k grid per axis over the centroid bounds (k = 10 for
/// 30-bit codes in uint32_t, k = 21 for 63-bit codes in uint64_t) and their bits interleaved
/// (x highest); `sort_references` then orders the references along that curve. An axis of
/// zero extent (a flat or point-like scene) quantises to 0 instead of dividing by zero, and non-finite inputs clamp into the grid. Lauterbach et al. 2009.
#pragma once

#include <array>
#include <cmath>
#include <cstdint>
#include <span>
#include <stdexcept>
#include <string>
#include <type_traits>

#include "../aabb.hpp"
#include "radix_sort.hpp"
#include "references.hpp"
#include "scratch.hpp"

namespace dynbvh::morton {

/// Throws std::invalid_argument naming `builder` unless `bits` is 30 (uint32 keys) or 63 (uint64 keys).
inline void check_bits(int bits, const char* builder) {
    if (bits != 30 && bits != 63)
        throw std::invalid_argument(std::string(builder) + ": morton_bits must be 30 or 63, got " + std::to_string(bits));
}

/// Spreads the low 10 bits of v so that two zero bits separate each: b9..b0 -> b9 0 0 b8 ... b0.
constexpr std::uint32_t spread10(std::uint32_t v) noexcept {
    v &= 0x3ffu;
    v = (v | (v << 16)) & 0x030000ffu;
    v = (v | (v << 8)) & 0x0300f00fu;
    v = (v | (v << 4)) & 0x030c30c3u;
    v = (v | (v << 2)) & 0x09249249u;
    return v;
}

/// Spreads the low 21 bits of v so that two zero bits separate each.
constexpr std::uint64_t spread21(std::uint64_t v) noexcept {
    v &= 0x1fffffull;
    v = (v | (v << 32)) & 0x001f00000000ffffull;
    v = (v | (v << 16)) & 0x001f0000ff0000ffull;
    v = (v | (v << 8)) & 0x100f00f00f00f00full;
    v = (v | (v << 4)) & 0x10c30c30c30c30c3ull;
    v = (v | (v << 2)) & 0x1249249249249249ull;
    return v;
}

namespace detail {
/// spread10 of every 10-bit value (4 KiB): one load per axis instead of four shift-and-mask steps.
inline constexpr auto spread10_table = [] {
    std::array<std::uint32_t, 1024> t{};
    for (std::uint32_t v = 0; v < 1024; ++v) t[v] = spread10(v);
    return t;
}();
} // namespace detail

/// 30-bit code of grid cell (x, y, z), each in [0, 1024).
constexpr std::uint32_t encode30(std::uint32_t x, std::uint32_t y, std::uint32_t z) noexcept {
    const auto& t = detail::spread10_table;
    return (t[x & 0x3ffu] << 2) | (t[y & 0x3ffu] << 1) | t[z & 0x3ffu];
}
/// 63-bit code of grid cell (x, y, z), each in [0, 2^21).
constexpr std::uint64_t encode63(std::uint64_t x, std::uint64_t y, std::uint64_t z) noexcept {
    // Cell bits 0-9 go to code bits 0-29, bits 10-19 to 30-59, bit 20 to 60.
    auto spread = [](std::uint64_t v) {
        const auto& t = detail::spread10_table;
        return std::uint64_t(t[v & 0x3ffu]) | (std::uint64_t(t[(v >> 10) & 0x3ffu]) << 30) | (((v >> 20) & 1u) << 60);
    };
    return (spread(x) << 2) | (spread(y) << 1) | spread(z);
}

/// Grid resolution per axis for a key type: 2^10 for uint32_t, 2^21 for uint64_t.
template <class Key>
inline constexpr std::uint32_t grid_bits = std::is_same_v<Key, std::uint32_t> ? 10u : 21u;
/// Meaningful bits in a code of this key type (30 or 63).
template <class Key>
inline constexpr int code_bits = 3 * static_cast<int>(grid_bits<Key>);

/// Maps points in `bounds` to integer grid cells [0, 2^bits) per axis. Survives flat and zero-size bounds.
template <class T>
struct Quantizer {
    Vec3<T> origin{};
    Vec3<T> scale{};   ///< cells per scene unit; 0 on an axis of zero extent
    T cells = 0;

    Quantizer() = default;
    Quantizer(const AABB<T>& bounds, std::uint32_t bits) noexcept : cells(T(std::uint64_t(1) << bits)) {
        if (bounds.is_empty()) return;
        origin = bounds.min;
        const Vec3<T> ext = bounds.diagonal();
        for (std::size_t a = 0; a < 3; ++a)
            scale[a] = (ext[a] > T(0) && std::isfinite(ext[a])) ? cells / ext[a] : T(0);
    }
    /// Cell of p on axis a, clamped into [0, cells - 1] (NaN maps to 0). Branch-free.
    std::uint64_t cell(const Vec3<T>& p, std::size_t a) const noexcept {
        T c = (p[a] - origin[a]) * scale[a];
        c = c > T(0) ? c : T(0);                         // negative, zero or NaN -> 0
        c = c < cells - T(1) ? c : cells - T(1);
        return static_cast<std::uint64_t>(static_cast<std::int64_t>(c));   // the signed conversion is one instruction
    }
};

/// Code of point p in a grid over `q`'s bounds.
template <class Key, class T>
Key encode(const Quantizer<T>& q, const Vec3<T>& p) noexcept {
    if constexpr (std::is_same_v<Key, std::uint32_t>)
        return encode30(std::uint32_t(q.cell(p, 0)), std::uint32_t(q.cell(p, 1)), std::uint32_t(q.cell(p, 2)));
    else
        return encode63(q.cell(p, 0), q.cell(p, 1), q.cell(p, 2));
}

/// Codes of every reference's box centre over the references' centroid bounds. O(n), parallel.
/// Key = std::uint32_t (30-bit codes) or std::uint64_t (63-bit codes).
template <class Key, class T, class Exec>
void codes(const References<T>& refs, std::span<Key> out, const Exec& ex) {
    static_assert(std::is_same_v<Key, std::uint32_t> || std::is_same_v<Key, std::uint64_t>);
    const Quantizer<T> q(refs.centroid_bounds, grid_bits<Key>);
    ex.for_each(0, refs.size(), [&](std::size_t i) { out[i] = encode<Key>(q, refs.box[i].center()); });
}

/// Reorders `refs` (boxes and triangle ids together) by the Morton code of their centres and
/// returns the sorted codes. Sorting the references themselves, not an index array, keeps every
/// later pass sequential in memory. Shared with PLOC. O(n), parallel.
template <class Key, class T, class Exec>
scratch_vector<Key> sort_references(References<T>& refs, const Exec& ex) {
    const std::size_t n = refs.size();
    scratch_vector<Key> keys(n);
    morton::codes<Key>(refs, std::span<Key>(keys), ex);
    const scratch_vector<std::uint32_t> order = radix_sort_order(keys, ex, morton::code_bits<Key>);
    scratch_vector<AABB<T>> box(n);
    scratch_vector<std::uint32_t> prim(n);
    ex.for_each(0, n, [&](std::size_t i) {
        box[i] = refs.box[order[i]];
        prim[i] = refs.prim[order[i]];
    });
    refs.box.swap(box);
    refs.prim.swap(prim);
    return keys;
}

} // namespace dynbvh::morton
