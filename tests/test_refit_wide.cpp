// Wide refit in place (refit.hpp, refit(WideBvh&, tris, ex)): after arbitrary vertex motion every slot
// box is exactly the union of what it holds (its triangles' boxes, or its child node's slots) and equals,
// bit for bit, the refitted binary tree's box of the binary node it stands for; hits equal brute force; for prim::copied the leaf
// triangles follow; mismatched triangle spans throw std::invalid_argument and leave the tree unchanged.
#include "builds.hpp"
#include "hit_compare.hpp"
#include "support.hpp"

#include <cstring>
#include <stdexcept>
#include <string>
#include <vector>

#include <dynbvh/refit.hpp>
#include <dynbvh/wide.hpp>

using namespace dynbvh;
using namespace dynbvh::test;

namespace {

/// Moves every vertex by a random offset up to `amount` (vertices shared by index would drift apart:
/// the test scenes are soups, and the refit must not care).
std::vector<Trianglef> moved(const std::vector<Trianglef>& tris, float amount, std::uint64_t seed) {
    Rng r(seed);
    std::vector<Trianglef> out = tris;
    for (auto& t : out)
        for (Vec3f* p : {&t.p0, &t.p1, &t.p2}) *p = *p + Vec3f{r.uniform(-amount, amount), r.uniform(-amount, amount), r.uniform(-amount, amount)};
    return out;
}

bool same_box(const AABB<float>& a, const AABB<float>& b) {
    return same_bits(a.min.x, b.min.x) && same_bits(a.min.y, b.min.y) && same_bits(a.min.z, b.min.z) &&
           same_bits(a.max.x, b.max.x) && same_bits(a.max.y, b.max.y) && same_bits(a.max.z, b.max.z);
}

/// Empty when every used slot's box equals the union recomputed here from the triangles (leaf) or the
/// child's slots (inner), else the first problem.
template <class WB>
std::string box_problems(const WB& w, std::span<const Trianglef> tris) {
    for (std::size_t i = 0; i < w.nodes.size(); ++i) {
        const auto& n = w.nodes[i];
        for (int k = 0; k < WB::width; ++k) {
            if (n.empty_slot(k)) continue;
            AABB<float> want;
            if (n.is_leaf(k)) {
                for (std::size_t s = n.child[k]; s < std::size_t(n.child[k]) + n.count[k]; ++s) want.extend(tris[w.prim_ids[s]].bounds());
            } else {
                want = w.nodes[n.child[k]].bounds();
            }
            if (!same_box(n.bounds(k), want)) return "node " + std::to_string(i) + " slot " + std::to_string(k) + " is not the union of its contents";
        }
    }
    return {};
}

template <class WB>
std::string difference(const WB& a, const WB& b) {
    if (a.nodes.size() != b.nodes.size()) return "node counts differ";
    for (std::size_t i = 0; i < a.nodes.size(); ++i)
        if (std::memcmp(&a.nodes[i], &b.nodes[i], sizeof(a.nodes[i])) != 0) return "node " + std::to_string(i) + " differs";
    if (a.prim_ids.size() != b.prim_ids.size() || a.leaf_triangles.size() != b.leaf_triangles.size()) return "leaf part sizes differ";
    for (std::size_t s = 0; s < a.prim_ids.size(); ++s)
        if (a.prim_ids[s] != b.prim_ids[s]) return "prim_ids differ";
    for (std::size_t s = 0; s < a.leaf_triangles.size(); ++s)
        if (std::memcmp(&a.leaf_triangles[s], &b.leaf_triangles[s], sizeof(Trianglef)) != 0) return "leaf triangle " + std::to_string(s) + " differs";
    return {};
}

/// Empty when every slot of `wide` (made by make_wide<W> from `orig`, then refitted) holds the box the
/// refitted binary tree `bin` (same topology as `orig`) has for the binary node the slot stands for, to
/// the bit, else the first problem. The slots' binary nodes are found by replaying the collapse on
/// `orig` (detail::open_wide): the wide topology is the one collapsed from the boxes before the motion
/// (make_wide of `bin` may open other nodes, as the areas changed).
template <int W, class WB, class B>
std::string slot_problems(const WB& wide, const B& orig, const B& bin) {
    using Index = typename B::index_type;
    if (orig.nodes.size() < 2) return same_box(wide.nodes[0].bounds(0), bin.nodes[0].bounds()) ? "" : "single leaf box differs";
    std::vector<std::pair<Index, Index>> todo{{0, 0}};   // (wide node, binary inner node)
    while (!todo.empty()) {
        const auto [w, b] = todo.back();
        todo.pop_back();
        Index c[W];
        const int n = detail::open_wide<W>(std::span<const typename B::node_type>(orig.nodes), b, c);
        for (int k = 0; k < W; ++k) {
            const auto& node = wide.nodes[w];
            if (k >= n) {
                if (!node.empty_slot(k)) return "slot " + std::to_string(k) + " of node " + std::to_string(w) + " should be empty";
                continue;
            }
            if (!same_box(node.bounds(k), bin.nodes[c[k]].bounds()))
                return "node " + std::to_string(w) + " slot " + std::to_string(k) + " differs from binary node " + std::to_string(c[k]);
            if (!node.is_leaf(k)) todo.push_back({node.child[k], c[k]});
        }
    }
    return {};
}

template <int W, class Prim, class Ex>
void check_refit(const char* what, const Bvh<Node<>, Prim>& bvh, const std::vector<Trianglef>& tris, const Ex& ex) {
    CAPTURE(what);
    CAPTURE(W);
    CAPTURE(executor_name<Ex>());
    for (float amount : {0.01f, 0.3f, 3.0f}) {
        CAPTURE(amount);
        const auto now = moved(tris, amount, 77 + std::uint64_t(amount * 100));
        const std::span<const Trianglef> t(now);
        auto wide = make_wide<W>(bvh, ex);
        refit(wide, t, ex);
        CHECK(box_problems(wide, t) == "");
        auto bin = bvh;
        refit(bin, t, ex);
        CHECK(slot_problems<W>(wide, bvh, bin) == "");
        if constexpr (std::is_same_v<Prim, prim::copied>)
            for (std::size_t s = 0; s < wide.prim_ids.size(); ++s)
                REQUIRE(std::memcmp(&wide.leaf_triangles[s], &now[wide.prim_ids[s]], sizeof(Trianglef)) == 0);
        // Hits after the motion equal brute force over the moved triangles.
        Rng rng(13);
        std::size_t bad = 0;
        for (std::size_t i = 0; i < sanitizer_scaled(200); ++i) {
            const Vec3f org{rng.uniform(-1, 2), rng.uniform(-1, 2), rng.uniform(-1, 2)};
            const Vec3f target{rng.uniform(), rng.uniform(), rng.uniform()};
            const Rayf ray{.org = org, .dir = target - org};
            if (!same_hit<tri::watertight>(intersect(wide, t, ray), brute_force_intersect(t, ray), t, ray)) ++bad;
        }
        CHECK(bad == 0);
    }
}

} // namespace

TEST_CASE("refit_wide: after vertex motion every slot box is the union of its contents and equals refit(binary)'s box of its node, exact hits") {
    const auto soup = random_soup(sanitizer_scaled(6000), 3);
    const auto ball = sphere(20, 40);
    for_each_executor([&](auto ex) {
        check_refit<8>("lbvh soup", lbvh::build(soup, {}, ex), soup, ex);
        check_refit<4>("ploc soup", ploc::build<Node<>, prim::indexed>(std::span<const Trianglef>(soup), {}, ex), soup, ex);
        check_refit<8>("kbvh sphere", kbvh::build<Node<>, prim::indexed>(std::span<const Trianglef>(ball), {.split = {.beta = 0.3f}}, ex), ball, ex);
        check_refit<8>("lbvh copied", lbvh::build<Node<>, prim::copied>(std::span<const Trianglef>(soup), {}, ex), soup, ex);
        check_refit<4>("lbvh copied, one triangle", lbvh::build<Node<>, prim::copied>(std::span<const Trianglef>(soup).first(1), {}, ex),
                       std::vector<Trianglef>(soup.begin(), soup.begin() + 1), ex);
    });
}

TEST_CASE("refit_wide: a tree built directly (build_wide) refits like the converted one") {
    const auto soup = random_soup(3000, 4);
    const auto now = moved(soup, 0.2f, 5);
    auto direct = lbvh::build_wide<8>(std::span<const Trianglef>(soup), {}, exec::serial{});
    auto converted = make_wide<8>(lbvh::build(soup, {}, exec::serial{}));
    refit(direct, std::span<const Trianglef>(now));
    refit(converted, std::span<const Trianglef>(now));
    CHECK(difference(direct, converted) == "");
    CHECK(box_problems(direct, std::span<const Trianglef>(now)) == "");
}

TEST_CASE("refit_wide: a triangle span of the wrong size throws std::invalid_argument naming refit; the tree is unchanged") {
    const auto soup = random_soup(1000, 6);
    auto wide = make_wide<8>(lbvh::build<Node<>, prim::copied>(std::span<const Trianglef>(soup), {}, exec::serial{}));
    const auto before = wide;
    const std::span<const Trianglef> t(soup);
    for (const auto bad : {t.first(999), t.first(0)}) {
        try {
            refit(wide, bad);
            FAIL("no exception for " << bad.size() << " triangles");
        } catch (const std::invalid_argument& e) {
            CHECK(std::string(e.what()).find("dynbvh::refit") == 0);
            CHECK(std::string(e.what()).find(std::to_string(bad.size())) != std::string::npos);
        }
        CHECK(difference(wide, before) == "");
    }
    std::vector<Trianglef> longer = soup;
    longer.push_back(soup[0]);
    CHECK_THROWS_AS(refit(wide, std::span<const Trianglef>(longer)), std::invalid_argument);
    CHECK(difference(wide, before) == "");
    // An empty tree over no triangles: nothing to do, no throw.
    auto empty = make_wide<4>(lbvh::build<Node<>, prim::indexed>(std::span<const Trianglef>(), {}, exec::serial{}));
    CHECK_NOTHROW(refit(empty, std::span<const Trianglef>()));
    CHECK(empty.empty());
}
