// Bytes allocated per frame by Dynamic::update over a MeshView after warm-up (issue 13's target for
// indexed input: no per-frame copy of the triangles). This executable replaces the global operator
// new/delete with counting ones, and counts std::aligned_alloc too (the scratch cache's system
// allocations, detail/scratch.hpp), so every heap allocation the library makes is seen. Not under the
// sanitizers (they own the allocator): the cases are skipped there.
#include <doctest/doctest.h>

#include <algorithm>
#include <atomic>
#include <cmath>
#include <cstddef>
#include <cstdint>
#include <cstdlib>
#include <limits>
#include <new>
#include <numbers>
#include <span>
#include <string>
#include <vector>

#include <dynbvh/builder.hpp>
#include <dynbvh/dynamic.hpp>
#include <dynbvh/mesh.hpp>

#if defined(__SANITIZE_ADDRESS__) || defined(__SANITIZE_THREAD__)
#define DYNBVH_ALLOC_COUNTING 0
#elif defined(__has_feature)
#if __has_feature(address_sanitizer) || __has_feature(thread_sanitizer) || __has_feature(memory_sanitizer)
#define DYNBVH_ALLOC_COUNTING 0
#endif
#endif
#ifndef DYNBVH_ALLOC_COUNTING
#define DYNBVH_ALLOC_COUNTING 1
#endif

namespace {
std::atomic<bool> counting{false};
std::atomic<std::size_t> counted_bytes{0}, counted_calls{0}, largest{0};
#if DYNBVH_ALLOC_COUNTING
void count(std::size_t n) noexcept {
    if (!counting.load(std::memory_order_relaxed)) return;
    counted_bytes.fetch_add(n, std::memory_order_relaxed);
    counted_calls.fetch_add(1, std::memory_order_relaxed);
    std::size_t l = largest.load(std::memory_order_relaxed);
    while (n > l && !largest.compare_exchange_weak(l, n, std::memory_order_relaxed)) {}
}
#endif
} // namespace

#if DYNBVH_ALLOC_COUNTING
extern "C" void* __libc_memalign(std::size_t alignment, std::size_t size);   // glibc's own aligned_alloc
extern "C" void* aligned_alloc(std::size_t alignment, std::size_t size) noexcept {
    count(size);
    return __libc_memalign(alignment, size);
}

void* operator new(std::size_t n) {
    count(n);
    if (void* p = std::malloc(n == 0 ? 1 : n)) return p;
    throw std::bad_alloc();
}
void* operator new[](std::size_t n) { return operator new(n); }
void* operator new(std::size_t n, const std::nothrow_t&) noexcept {
    count(n);
    return std::malloc(n == 0 ? 1 : n);
}
void* operator new[](std::size_t n, const std::nothrow_t& t) noexcept { return operator new(n, t); }
void* operator new(std::size_t n, std::align_val_t a) {
    count(n);
    const std::size_t al = std::max(std::size_t(a), sizeof(void*));
    if (void* p = __libc_memalign(al, n == 0 ? al : n)) return p;
    throw std::bad_alloc();
}
void* operator new[](std::size_t n, std::align_val_t a) { return operator new(n, a); }
void operator delete(void* p) noexcept { std::free(p); }
void operator delete[](void* p) noexcept { std::free(p); }
void operator delete(void* p, std::size_t) noexcept { std::free(p); }
void operator delete[](void* p, std::size_t) noexcept { std::free(p); }
void operator delete(void* p, std::align_val_t) noexcept { std::free(p); }
void operator delete[](void* p, std::align_val_t) noexcept { std::free(p); }
void operator delete(void* p, std::size_t, std::align_val_t) noexcept { std::free(p); }
void operator delete[](void* p, std::size_t, std::align_val_t) noexcept { std::free(p); }
#endif

using namespace dynbvh;

namespace {

struct Counted {
    std::size_t bytes, calls, largest;
};

template <class F>
Counted measure(F&& f) {
    counted_bytes = 0;
    counted_calls = 0;
    largest = 0;
    counting = true;
    f();
    counting = false;
    return {counted_bytes.load(), counted_calls.load(), largest.load()};
}

/// A UV sphere as an indexed mesh with shared vertices (2 * stacks * slices triangles).
struct Sphere {
    std::vector<Vec3f> vertices;
    std::vector<std::uint32_t> indices;
    Sphere(int stacks, int slices) {
        for (int i = 0; i <= stacks; ++i)
            for (int j = 0; j < slices; ++j) {
                const double th = std::numbers::pi * i / stacks, ph = 2 * std::numbers::pi * j / slices;
                vertices.push_back({float(std::sin(th) * std::cos(ph)), float(std::cos(th)), float(std::sin(th) * std::sin(ph))});
            }
        const auto id = [&](int i, int j) { return std::uint32_t(i * slices + (j % slices)); };
        for (int i = 0; i < stacks; ++i)
            for (int j = 0; j < slices; ++j) {
                indices.insert(indices.end(), {id(i, j), id(i + 1, j), id(i + 1, j + 1)});
                indices.insert(indices.end(), {id(i, j), id(i + 1, j + 1), id(i, j + 1)});
            }
    }
    MeshView<float> view() const { return {std::span<const Vec3f>(vertices), std::span<const std::uint32_t>(indices)}; }
    std::vector<Trianglef> flat() const { return make_triangles(std::span<const Vec3f>(vertices), std::span<const std::uint32_t>(indices)); }
    void move(int frame) {   // in place, as an animation would
        for (Vec3f& v : vertices) v.x += 0.01f * std::sin(float(frame) + 5.0f * v.y);
    }
};

constexpr bool skip_counting = DYNBVH_ALLOC_COUNTING == 0;

/// Tree arrays' bytes (what a rebuild must allocate anew: the tree it returns).
template <class B>
std::size_t tree_bytes(const B& b) {
    return b.nodes.capacity() * sizeof(b.nodes[0]) + b.prim_ids.capacity() * sizeof(b.prim_ids[0]) +
           b.leaf_triangles.capacity() * sizeof(Trianglef);
}

/// dyn.update(src), counted; requires the decision `want`.
template <class D, class Src>
Counted counted_update(D& dyn, const Src& src, Decision want) {
    FrameReport r;
    const Counted c = measure([&] { r = dyn.update(src); });
    REQUIRE(r.decision == want);
    return c;
}

constexpr double never = std::numeric_limits<double>::infinity();

} // namespace

TEST_CASE("mesh view alloc: refit frames of Dynamic::update(view) allocate nothing" * doctest::skip(skip_counting)) {
    Sphere s(128, 256);   // 65536 triangles
    const MeshView<float> view = s.view();
    const auto n = view.size();
    Dynamic<builder::ploc, Node<>, prim::indexed, exec::serial> indexed({.rebuild_threshold = never});
    Dynamic<builder::ploc, Node<>, prim::copied, exec::serial> copied({.rebuild_threshold = never});
    for (int f = 0; f < 2; ++f) {   // warm-up: the first frame builds
        s.move(f);
        indexed.update(view);
        copied.update(view);
    }
    for (int f = 2; f < 6; ++f) {
        s.move(f);
        const Counted ci = counted_update(indexed, view, Decision::refit);
        const Counted cc = counted_update(copied, view, Decision::refit);
        MESSAGE("refit frame, ", n, " triangles: indexed ", ci.bytes, " bytes in ", ci.calls, " allocations; copied ", cc.bytes,
                " bytes in ", cc.calls);
        CHECK(ci.bytes == 0);
        CHECK(ci.calls == 0);
        CHECK(cc.bytes == 0);
        CHECK(cc.calls == 0);
    }
    // The span path, for comparison (also none): the flattened copy the view saves is the user's
    // make_triangles, n * 36 bytes per frame, measured here.
    std::vector<Trianglef> flat = s.flat();
    Dynamic<builder::ploc, Node<>, prim::indexed, exec::serial> over_span({.rebuild_threshold = never});
    over_span.update(flat);
    over_span.update(flat);
    const Counted cs = counted_update(over_span, flat, Decision::refit);
    const Counted flatten = measure([&] { flat = s.flat(); });
    MESSAGE("span path refit frame: ", cs.bytes, " bytes; make_triangles per frame: ", flatten.bytes, " bytes");
    CHECK(cs.bytes == 0);
    CHECK(flatten.bytes == n * sizeof(Trianglef));
}

TEST_CASE("mesh view alloc: rebuild frames allocate nothing per triangle beyond the tree" * doctest::skip(skip_counting)) {
    // Large enough that every per-triangle array (the tree's and the builder's) is above the scratch cache's
    // threshold (min_cached): those come back from the cache after warm-up (detail/scratch.hpp).
    Sphere s(256, 520);   // 266240 triangles (not 2^18: (n - 1) * 4 bytes would fall just below the cache threshold)
    const MeshView<float> view = s.view();
    const std::size_t n = view.size();
    Dynamic<builder::ploc, Node<>, prim::indexed, exec::serial> dyn({.rebuild_threshold = 0});   // rebuilds every frame
    std::vector<Trianglef> flat = s.flat();
    Dynamic<builder::ploc, Node<>, prim::indexed, exec::serial> over_span({.rebuild_threshold = 0});
    for (int f = 0; f < 3; ++f) {   // warm-up: the scratch cache fills
        dyn.update(view);
        over_span.update(flat);
    }
    for (int f = 3; f < 5; ++f) {
        s.move(f);
        flat = s.flat();
        const Counted c = counted_update(dyn, view, Decision::rebuild);
        const Counted cs = counted_update(over_span, flat, Decision::rebuild);
        MESSAGE("rebuild frame, ", n, " triangles: view ", c.bytes, " bytes in ", c.calls, " allocations (largest ", c.largest,
                "), span ", cs.bytes, " bytes in ", cs.calls, " (largest ", cs.largest, "); tree arrays ", tree_bytes(dyn.bvh()),
                " bytes; one triangle copy ", n * sizeof(Trianglef), " bytes");
        // What is checked: the view path allocates exactly what the span path does (one code path, no
        // copy of the triangles); in all less than 1 byte per triangle, and no single block above 64 KiB:
        // every per-triangle array (the tree's included) is reused from the scratch cache, what remains
        // are small per-task and per-iteration vectors (measured: about 90 KB in about 650 blocks, the
        // largest 8 KiB, at 266240 triangles).
        CHECK(c.bytes == cs.bytes);
        CHECK(c.bytes < n);
        CHECK(c.largest <= 65536);
    }
}
