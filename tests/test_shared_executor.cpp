// One executor object shared by several threads at once (issue 16.2): builders take the executor by
// const&, so two threads building (or one building and one refitting) with the same object is
// legitimate. exec::tbb{n} creates its private arena on first use; the scratch cache is shared by every
// build. The trees must equal a serial build bit for bit, and tools/tsan.sh must report no race.
#include <doctest/doctest.h>

#include <dynbvh/executor.hpp>
#include <dynbvh/lbvh.hpp>
#include <dynbvh/ploc.hpp>
#include <dynbvh/refit.hpp>
#include <dynbvh/detail/scratch.hpp>
#include <dynbvh/validate.hpp>

#include <cstring>
#include <span>
#include <string>
#include <thread>
#include <vector>

#include "builds.hpp"
#include "support.hpp"

using namespace dynbvh;

namespace {

template <class B>
bool same_bvh(const B& a, const B& b) {
    return a.nodes.size() == b.nodes.size() && a.prim_ids.size() == b.prim_ids.size() && a.depth == b.depth &&
           std::memcmp(a.nodes.data(), b.nodes.data(), a.nodes.size() * sizeof(a.nodes[0])) == 0 &&
           std::memcmp(a.prim_ids.data(), b.prim_ids.data(), a.prim_ids.size() * sizeof(a.prim_ids[0])) == 0;
}

/// A moved copy of `tris` (the refit input).
std::vector<Trianglef> moved(std::span<const Trianglef> tris, float d) {
    std::vector<Trianglef> out(tris.begin(), tris.end());
    for (std::size_t i = 0; i < out.size(); ++i) {
        const Vec3f o{d * float(i % 7), -d * float(i % 5), d};
        out[i] = {out[i].p0 + o, out[i].p1 + o, out[i].p2 + o};
    }
    return out;
}

/// Two threads, started together, on the same executor object `ex` (never used before, so the
/// lazily created state is created by them): thread A builds LBVH then PLOC, thread B builds PLOC
/// then refits a tree. Repeated with a fresh object each round so every first use is concurrent.
template <class E, class MakeExec>
void shared_rounds(MakeExec make, int rounds) {
    const auto tris = test::random_soup(test::sanitizer_scaled(30000, 4), 5);
    const auto tris2 = moved(tris, 0.01f);
    const exec::serial s;
    const auto ref_lbvh = lbvh::build(tris, {}, s);
    const auto ref_ploc = ploc::build(tris, {}, s);
    auto ref_refit = lbvh::build(tris, {}, s);
    refit(ref_refit, tris2, s);
    REQUIRE(validate(ref_refit, tris2).ok());
    for (int r = 0; r < rounds; ++r) {
        const E ex = make();
        Bvh<> a_lbvh, a_ploc, b_ploc, b_refit = lbvh::build(tris, {}, s);
        std::thread a([&] {
            a_lbvh = lbvh::build(tris, {}, ex);
            a_ploc = ploc::build(tris, {}, ex);
        });
        std::thread b([&] {
            refit(b_refit, tris2, ex);
            b_ploc = ploc::build(tris, {}, ex);
        });
        a.join();
        b.join();
        CHECK(same_bvh(a_lbvh, ref_lbvh));
        CHECK(same_bvh(a_ploc, ref_ploc));
        CHECK(same_bvh(b_ploc, ref_ploc));
        CHECK(same_bvh(b_refit, ref_refit));
    }
}

} // namespace

TEST_CASE("shared executor: two threads build and refit with one executor object") {
    const int rounds = test::sanitized() ? 2 : 4;
    if (test::executor_selected<exec::serial>()) {
        INFO("serial");
        shared_rounds<exec::serial>([] { return exec::serial{}; }, rounds);
    }
#if defined(_OPENMP)
    if (test::executor_selected<exec::omp>()) {
        INFO("omp{2}");
        shared_rounds<exec::omp>([] { return exec::omp{2}; }, rounds);
    }
#endif
#if defined(DYNBVH_WITH_TBB)
    if (test::executor_selected<exec::tbb>()) {
        INFO("tbb{2}");
        shared_rounds<exec::tbb>([] { return exec::tbb{2}; }, rounds);
        INFO("tbb{} (default arena)");
        shared_rounds<exec::tbb>([] { return exec::tbb{}; }, 1);
        // A copy shares the original's arena; both used at once.
        const exec::tbb orig{2};
        const exec::tbb copy = orig;
        const auto tris = test::random_soup(20000, 9);
        const auto ref = lbvh::build(tris, {}, exec::serial{});
        Bvh<> x, y;
        std::thread t1([&] { x = lbvh::build(tris, {}, orig); });
        std::thread t2([&] { y = lbvh::build(tris, {}, copy); });
        t1.join();
        t2.join();
        CHECK(same_bvh(x, ref));
        CHECK(same_bvh(y, ref));
    }
#endif
}

TEST_CASE("shared executor: the scratch cache under two threads building at once") {
    // Both threads take and give cached blocks of the same sizes at the same time.
    set_scratch_limit(std::size_t(64) << 20);
    const auto tris = test::random_soup(test::sanitizer_scaled(40000, 4), 6);
    const auto ref = lbvh::build(tris, {}, exec::serial{});
    std::vector<std::thread> ts;
    std::vector<int> ok(3, 0);
    for (int k = 0; k < 3; ++k)
        ts.emplace_back([&, k] {
            bool all = true;
            for (int r = 0; r < 3; ++r) all = all && same_bvh(lbvh::build(tris, {}, exec::serial{}), ref);
            ok[std::size_t(k)] = all;
        });
    for (auto& t : ts) t.join();
    for (int k = 0; k < 3; ++k) CHECK(ok[std::size_t(k)] == 1);
    set_scratch_limit(std::size_t(4) << 30);
}
