// SPDX-License-Identifier: MIT
/// @file detail/scratch.hpp
/// Scratch memory for the builders' temporary arrays. A dynamic scene rebuilds every
/// frame with the same array sizes; fresh allocations of that size come from the kernel
/// as new pages, and faulting them in (and zeroing them) can cost more than the build.
/// Large blocks freed by a build are therefore kept in a small process-wide cache and
/// handed to the next build. `scratch_vector<T>` also leaves elements uninitialised on
/// resize (default-initialisation), since every builder overwrites what it allocates.
/// Call `release_scratch()` to return the cached memory to the system. The cache lives until the
/// process exits (it is never destroyed), so scratch-backed objects are safe in any static order.
#pragma once

#include <algorithm>
#include <cstddef>
#include <cstdlib>
#include <mutex>
#include <new>
#include <vector>

namespace dynbvh {

namespace detail {

/// Process-wide cache of freed large blocks (best fit, bounded total size).
class ScratchPool {
public:
    /// Smaller blocks (after rounding) bypass the cache. 128 KiB is glibc's default mmap threshold: a
    /// block that size or larger comes from the kernel as fresh pages at each allocation, and faulting
    /// those in dominated the presplit's per-build arrays of ~100k-triangle scenes (0.4-0.8 MiB each;
    /// measured on a VM where a page fault costs microseconds).
    static constexpr std::size_t min_cached = std::size_t(128) << 10;
    static constexpr std::size_t alignment = 64;

    /// The pool is never destroyed (deliberately leaked; its blocks stay reachable, so leak checkers
    /// are quiet): objects with static storage duration (a namespace-scope Bvh, ...) return their
    /// blocks during static destruction, in any order, possibly after a function-local pool would
    /// have been destroyed. The system reclaims the memory at exit.
    static ScratchPool& instance() {
        static ScratchPool* const pool = new ScratchPool;
        return *pool;
    }
    /// Bytes a request of `bytes` really takes: rounded up to the alignment. The cache threshold and
    /// the best fit compare this size, in take and give alike (comparing the unrounded size missed the
    /// cache for arrays just below the threshold that round up to it, every rebuild).
    static constexpr std::size_t rounded(std::size_t bytes) noexcept {
        return bytes == 0 ? alignment : (bytes + alignment - 1) / alignment * alignment;
    }
    /// Bytes of a fresh cached block for a request of `size` (rounded, at least min_cached): an eighth
    /// more room, since arrays sized by the tree (its node count) vary a little from frame to frame and
    /// the next frame's slightly larger request then still fits the block (untouched pages of the margin
    /// are never faulted in).
    static constexpr std::size_t block_size(std::size_t size) noexcept { return rounded(size + size / 8); }
    void* take(std::size_t bytes) {
        const std::size_t size = rounded(bytes);
        if (size >= min_cached) {
            std::lock_guard lock(mutex_);
            std::size_t best = blocks_.size();
            for (std::size_t i = 0; i < blocks_.size(); ++i)
                if (blocks_[i].size >= size && blocks_[i].size <= 2 * size &&
                    (best == blocks_.size() || blocks_[i].size < blocks_[best].size))
                    best = i;
            if (best != blocks_.size()) {
                void* p = blocks_[best].ptr;
                cached_ -= blocks_[best].size;
                sizes_.push_back({p, blocks_[best].size});
                blocks_.erase(blocks_.begin() + std::ptrdiff_t(best));
                return p;
            }
        }
        const std::size_t block = size >= min_cached ? block_size(size) : size;
        void* p = std::aligned_alloc(alignment, block);
        if (!p) throw std::bad_alloc();
        if (size >= min_cached) {
            std::lock_guard lock(mutex_);
            sizes_.push_back({p, block});
        }
        return p;
    }
    void give(void* p, std::size_t bytes) {
        if (!p) return;
        if (rounded(bytes) >= min_cached) {
            std::lock_guard lock(mutex_);
            const auto it = std::find_if(sizes_.begin(), sizes_.end(), [p](const Block& b) { return b.ptr == p; });
            const std::size_t size = it != sizes_.end() ? it->size : rounded(bytes);
            if (it != sizes_.end()) sizes_.erase(it);
            blocks_.push_back({p, size});
            cached_ += size;
            while (cached_ > limit_ && !blocks_.empty()) {   // drop the oldest blocks beyond the limit
                cached_ -= blocks_.front().size;
                std::free(blocks_.front().ptr);
                blocks_.erase(blocks_.begin());
            }
            return;
        }
        std::free(p);
    }
    void release() {
        std::lock_guard lock(mutex_);
        for (const Block& b : blocks_) std::free(b.ptr);
        blocks_.clear();
        cached_ = 0;
    }
    void set_limit(std::size_t bytes) {
        { std::lock_guard lock(mutex_); limit_ = bytes; }
        if (bytes == 0) release();
    }
    std::size_t cached_bytes() const {
        std::lock_guard lock(mutex_);
        return cached_;
    }
    ~ScratchPool() { release(); }

private:
    struct Block { void* ptr; std::size_t size; };
    mutable std::mutex mutex_;
    std::vector<Block> blocks_;   ///< free blocks
    std::vector<Block> sizes_;    ///< blocks in use, with their real sizes
    std::size_t cached_ = 0;
    std::size_t limit_ = std::size_t(4) << 30;
};

} // namespace detail

/// Allocator for builder scratch arrays: large blocks come from and return to the scratch cache;
/// `construct()` without arguments default-initialises (no zeroing of arrays that are overwritten).
template <class T>
struct ScratchAllocator {
    using value_type = T;
    ScratchAllocator() = default;
    template <class U> ScratchAllocator(const ScratchAllocator<U>&) noexcept {}
    T* allocate(std::size_t n) { return static_cast<T*>(detail::ScratchPool::instance().take(n * sizeof(T))); }
    void deallocate(T* p, std::size_t n) noexcept { detail::ScratchPool::instance().give(p, n * sizeof(T)); }
    template <class U> void construct(U* p) noexcept(noexcept(::new (static_cast<void*>(p)) U)) { ::new (static_cast<void*>(p)) U; }
    template <class U, class... Args> void construct(U* p, Args&&... args) { ::new (static_cast<void*>(p)) U(std::forward<Args>(args)...); }
    template <class U> friend bool operator==(const ScratchAllocator&, const ScratchAllocator<U>&) noexcept { return true; }
};

/// A std::vector for builder temporaries (see the file comment).
template <class T>
using scratch_vector = std::vector<T, ScratchAllocator<T>>;

/// Frees the cached scratch blocks (they are otherwise kept for the next build).
inline void release_scratch() { detail::ScratchPool::instance().release(); }
/// Caps the scratch cache at `bytes` (default 4 GiB); 0 disables caching.
inline void set_scratch_limit(std::size_t bytes) { detail::ScratchPool::instance().set_limit(bytes); }
/// Bytes currently cached for reuse.
inline std::size_t scratch_cached_bytes() { return detail::ScratchPool::instance().cached_bytes(); }

} // namespace dynbvh
