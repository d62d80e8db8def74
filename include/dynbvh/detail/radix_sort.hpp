// SPDX-License-Identifier: MIT
/// @file detail/radix_sort.hpp
/// Parallel stable LSD radix sort of unsigned keys with a payload, shared by every
/// Morton-ordered builder. Up to 11-bit digits; each pass builds per-task histograms, scans
/// them (digit-major) and scatters; a pass whose digit is the same for every key is skipped.
/// `radix_sort_order` sorts keys and returns the permutation, its first pass writing the
/// original positions directly (no identity array to build and read).
/// O(n * passes) work, O(n) extra memory.
#pragma once

#include <algorithm>
#include <array>
#include <cstdint>
#include <type_traits>
#include <vector>

#include "../executor.hpp"
#include "scratch.hpp"

namespace dynbvh {

namespace detail {

/// The sort behind radix_sort and radix_sort_order. With `identity` the values are not read until the
/// first pass that moves keys: value i is taken to be i (and written as such when no pass moves any).
template <class Key, class Value, class KeyAlloc, class ValueAlloc, class Exec>
void radix_sort_impl(std::vector<Key, KeyAlloc>& keys, std::vector<Value, ValueAlloc>& values, const Exec& ex,
                     int key_bits, bool identity) {
    static_assert(std::is_unsigned_v<Key>);
    const std::size_t n = keys.size();
    if (n < 2 || key_bits <= 0) {
        if (identity) for (std::size_t i = 0; i < n; ++i) values[i] = static_cast<Value>(i);
        return;
    }
    const int passes = (key_bits + 10) / 11;
    const int digit_bits = (key_bits + passes - 1) / passes;
    const std::size_t buckets = std::size_t(1) << digit_bits;
    const Key mask = Key(buckets - 1);

    // Chunks of at least 16Ki keys: a 100k-key sort (a 100k-triangle scene) already runs on 2+ workers.
    std::size_t tasks = std::min<std::size_t>(ex.concurrency(), std::max<std::size_t>(1, n / 16384));
    if (tasks == 0) tasks = 1;
    const std::size_t chunk = (n + tasks - 1) / tasks;

    std::vector<Key, KeyAlloc> keys_tmp(n);
    std::vector<Value, ValueAlloc> values_tmp(n);
    scratch_vector<std::size_t> hist(tasks * buckets);
    Key* src_k = keys.data();
    Key* dst_k = keys_tmp.data();
    Value* src_v = values.data();
    Value* dst_v = values_tmp.data();

    for (int shift = 0; shift < key_bits; shift += digit_bits) {
        ex.for_tasks(tasks, [&](std::size_t t) {
            std::size_t* h = hist.data() + t * buckets;
            std::fill(h, h + buckets, std::size_t(0));
            const std::size_t lo = std::min(n, t * chunk), hi = std::min(n, lo + chunk);
            for (std::size_t i = lo; i < hi; ++i) ++h[(src_k[i] >> shift) & mask];
        });
        // Skip the pass when one digit value holds every key.
        bool trivial = false;
        for (std::size_t d = 0; d < buckets && !trivial; ++d) {
            std::size_t total = 0;
            for (std::size_t t = 0; t < tasks; ++t) total += hist[t * buckets + d];
            if (total == n) trivial = true;
            else if (total != 0) break;
        }
        if (trivial) continue;
        // Digit-major exclusive scan: all of digit 0 (task 0, 1, ...), then digit 1, ...
        std::size_t sum = 0;
        for (std::size_t d = 0; d < buckets; ++d)
            for (std::size_t t = 0; t < tasks; ++t) {
                const std::size_t c = hist[t * buckets + d];
                hist[t * buckets + d] = sum;
                sum += c;
            }
        const bool first = identity;
        ex.for_tasks(tasks, [&](std::size_t t) {
            std::size_t* h = hist.data() + t * buckets;
            const std::size_t lo = std::min(n, t * chunk), hi = std::min(n, lo + chunk);
            if (first) {
                for (std::size_t i = lo; i < hi; ++i) {
                    const std::size_t pos = h[(src_k[i] >> shift) & mask]++;
                    dst_k[pos] = src_k[i];
                    dst_v[pos] = static_cast<Value>(i);
                }
            } else {
                for (std::size_t i = lo; i < hi; ++i) {
                    const std::size_t pos = h[(src_k[i] >> shift) & mask]++;
                    dst_k[pos] = src_k[i];
                    dst_v[pos] = src_v[i];
                }
            }
        });
        identity = false;
        std::swap(src_k, dst_k);
        std::swap(src_v, dst_v);
    }
    if (src_k != keys.data()) {
        keys.swap(keys_tmp);
        values.swap(values_tmp);
    }
    if (identity) ex.for_each(0, n, [&](std::size_t i) { values[i] = static_cast<Value>(i); });   // no pass moved a key
}

} // namespace detail

/// Sorts `keys` ascending and applies the same permutation to `values` (stable).
/// Only the low `key_bits` bits are examined (higher bits must be zero, e.g. 30 for 30-bit
/// Morton codes): ceil(key_bits / 11) passes of at most 11-bit digits (30 bits: 3 passes of 10).
template <class Key, class Value, class KeyAlloc, class ValueAlloc, class Exec>
void radix_sort(std::vector<Key, KeyAlloc>& keys, std::vector<Value, ValueAlloc>& values, const Exec& ex,
                int key_bits = int(sizeof(Key) * 8)) {
    detail::radix_sort_impl(keys, values, ex, key_bits, false);
}

/// Sorts `keys` ascending (stable, as radix_sort) and returns the permutation: element i of the
/// result is the original position of the i-th smallest key. Fewer than 2^32 keys.
template <class Key, class KeyAlloc, class Exec>
scratch_vector<std::uint32_t> radix_sort_order(std::vector<Key, KeyAlloc>& keys, const Exec& ex,
                                               int key_bits = int(sizeof(Key) * 8)) {
    scratch_vector<std::uint32_t> order(keys.size());
    detail::radix_sort_impl(keys, order, ex, key_bits, true);
    return order;
}

} // namespace dynbvh
