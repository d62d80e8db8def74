// PLOC (ploc.hpp): raw topology invariants on hard inputs, every executor, determinism across executors,
// the first iteration against brute force, both schedules against plain serial versions (PLOC, H-PLOC),
// full builds through emit_bvh, SAH against LBVH on the bunny.
#include <doctest/doctest.h>

#include <dynbvh/io/ply.hpp>
#include <dynbvh/lbvh.hpp>
#include <dynbvh/ploc.hpp>
#include <dynbvh/sah.hpp>
#include <dynbvh/validate.hpp>
#include <dynbvh/wide_blocks.hpp>

#include <algorithm>
#include <cstdint>
#include <cstring>
#include <limits>
#include <span>
#include <string>
#include <tuple>
#include <utility>
#include <vector>

#include "support.hpp"

using namespace dynbvh;
using test::flat_scene;
using test::identical;
using test::random_soup;
using test::check_topology;

namespace {

template <class Exec>
BinaryTree tree_of(std::span<const Trianglef> tris, const ploc::Config& cfg, const Exec& ex) {
    auto refs = make_references(tris, ex);
    return ploc::build_tree(refs, cfg, ex);
}

bool same_tree(const BinaryTree& a, const BinaryTree& b) {
    return a.root == b.root && a.left == b.left && a.right == b.right;
}

/// Runs f(executor, name) for every executor this build has; `more_threads` adds an odd OpenMP thread
/// count (different block splits), which must not change the result either.
template <class F>
void for_each_executor(F&& f, bool more_threads = false) {
    f(exec::serial{}, std::string("serial"));
#if defined(_OPENMP)
    f(exec::omp{2}, std::string("omp2"));
    if (more_threads) f(exec::omp{3}, std::string("omp3"));
#endif
#if defined(DYNBVH_WITH_TBB)
    f(exec::tbb{2}, std::string("tbb2"));
#endif
    (void)more_threads;
}

} // namespace

TEST_CASE("ploc: empty input gives an empty tree") {
    const std::vector<Trianglef> none;
    const BinaryTree tree = tree_of(none, {}, exec::serial{});
    CHECK(tree.inner_count() == 0);
}

TEST_CASE("ploc: one and two triangles") {
    const auto tris = random_soup(2, 7);
    for_each_executor([&](const auto& ex, const std::string& name) {
        CAPTURE(name);
        const BinaryTree one = tree_of(std::span(tris.data(), 1), {}, ex);
        check_topology(one, 1);
        const BinaryTree two = tree_of(std::span(tris.data(), 2), {}, ex);
        check_topology(two, 2);
        CHECK(two.root == 0);
        // The only possible tree: both leaves under the root, in Morton order.
        CHECK(((two.left[0] == BinaryTree::leaf(0) && two.right[0] == BinaryTree::leaf(1)) ||
               (two.left[0] == BinaryTree::leaf(1) && two.right[0] == BinaryTree::leaf(0))));
    });
}

TEST_CASE("ploc: random soup topology, every executor, radius 1, 5 and 32, both code widths") {
    const auto tris = random_soup(10000, 1);
    for (std::uint32_t radius : {1u, 5u, 32u})
        for (int bits : {30, 63}) {
            if (bits == 63 && radius != 5) continue;
            for_each_executor([&](const auto& ex, const std::string& name) {
                CAPTURE(name);
                CAPTURE(radius);
                CAPTURE(bits);
                for (std::uint32_t sub : {0u, 8u}) {   // the original schedule and the hierarchical one
                    CAPTURE(sub);
                    check_topology(tree_of(tris, {.radius = radius, .morton_bits = bits, .subtree_clusters = sub}, ex), tris.size());
                }
            });
        }
}

TEST_CASE("ploc: the tree is identical on every executor") {
    // Large enough that every parallel path runs (scans switch to parallel above 2^14 clusters).
    const auto tris = random_soup(30000, 2);
    for (std::uint32_t radius : {1u, 5u, 16u}) {
        CAPTURE(radius);
        const BinaryTree ref = tree_of(tris, {.radius = radius, .subtree_clusters = 0}, exec::serial{});
        check_topology(ref, tris.size());
        for_each_executor([&](const auto& ex, const std::string& name) {
            CAPTURE(name);
            CHECK(same_tree(tree_of(tris, {.radius = radius, .subtree_clusters = 0}, ex), ref));
        }, true);
    }
}

TEST_CASE("ploc: all-identical triangles terminate with a shallow tree") {
    // Every box equal: every distance ties, so only the tie-break decides the merges.
    const std::vector<Trianglef> tris(5000, Trianglef{{0, 0, 0}, {1, 0, 0}, {0, 1, 0}});
    for_each_executor([&](const auto& ex, const std::string& name) {
        CAPTURE(name);
        for (std::uint32_t radius : {1u, 5u, 32u}) {
            CAPTURE(radius);
            for (std::uint32_t sub : {0u, 8u}) {
                CAPTURE(sub);
                const std::size_t depth = check_topology(tree_of(tris, {.radius = radius, .subtree_clusters = sub}, ex), tris.size());
                CHECK(depth <= 14);  // pairwise merging halves the clusters every iteration: ceil(log2 5000) = 13
            }
        }
    });
}

TEST_CASE("ploc: identical centroids with nested boxes terminate") {
    // Concentric triangles growing with the index: in Morton (= input) order each cluster's nearest
    // neighbour is the next smaller one, so mutual pairs are rare and only the progress guard keeps the
    // iteration count logarithmic.
    std::vector<Trianglef> tris;
    for (int i = 0; i < 20000; ++i) {
        const float s = 1.0f + 0.001f * float(i);
        tris.push_back({{-s, -s, 0}, {2 * s, -s, 0}, {-s, 2 * s, 0}});
    }
    for_each_executor([&](const auto& ex, const std::string& name) {
        CAPTURE(name);
        check_topology(tree_of(tris, {.subtree_clusters = 0}, ex), tris.size());
        check_topology(tree_of(tris, {}, ex), tris.size());
    });
}

TEST_CASE("ploc: degenerate point triangles at one spot") {
    const std::vector<Trianglef> tris(3001, Trianglef{{1, 2, 3}, {1, 2, 3}, {1, 2, 3}});
    for_each_executor([&](const auto& ex, const std::string& name) {
        CAPTURE(name);
        check_topology(tree_of(tris, {.radius = 5}, ex), tris.size());
    });
}

TEST_CASE("ploc: flat scene (all z = 0)") {
    const auto tris = flat_scene(10000, 3);
    for_each_executor([&](const auto& ex, const std::string& name) {
        CAPTURE(name);
        check_topology(tree_of(tris, {}, ex), tris.size());
    });
}

TEST_CASE("ploc: non-finite triangles are left out of the references") {
    auto tris = random_soup(1000, 4);
    tris[10].p1.x = std::numeric_limits<float>::quiet_NaN();
    tris[500].p2.z = std::numeric_limits<float>::infinity();
    auto refs = make_references(std::span<const Trianglef>(tris), exec::serial{});
    REQUIRE(refs.size() == 998);
    check_topology(ploc::build_tree(refs, {}, exec::serial{}), refs.size());
}

TEST_CASE("ploc: huge coordinates whose merged areas overflow") {
    // Half areas of merged boxes overflow to inf (and inf * 0 to NaN): distances must stay ordered.
    std::vector<Trianglef> tris;
    test::Rng rng(5);
    auto big = [&] { return 3e38f * rng.uniform(-1.0f, 1.0f); };
    for (int i = 0; i < 3000; ++i) {
        const Vec3f a{big(), big(), 0.0f};
        tris.push_back({a, {big(), big(), 0.0f}, a});
    }
    REQUIRE(make_references(std::span<const Trianglef>(tris), exec::serial{}).size() == tris.size());
    for_each_executor([&](const auto& ex, const std::string& name) {
        CAPTURE(name);
        check_topology(tree_of(tris, {.subtree_clusters = 0}, ex), tris.size());
        check_topology(tree_of(tris, {}, ex), tris.size());
    });
}

TEST_CASE("ploc: bad config is a clear error") {
    const auto tris = random_soup(10, 6);
    CHECK_THROWS_AS(tree_of(tris, {.morton_bits = 32}, exec::serial{}), std::invalid_argument);
    check_topology(tree_of(tris, {.radius = 0}, exec::serial{}), tris.size());  // 0 acts as 1
}

TEST_CASE("ploc: refs end up in Morton order, and the first iteration merges mutual nearest neighbours") {
    // Brute force over the reordered references: with positions = leaf ids, every pair of mutual nearest
    // neighbours within the radius (distance = half area of the merged box) must be among the first merges.
    const auto tris = random_soup(64, 8, 0.2f);
    auto refs = make_references(std::span<const Trianglef>(tris), exec::serial{});
    const auto original = refs.prim;
    const ploc::Config cfg{.radius = 3, .subtree_clusters = 0};
    const BinaryTree tree = ploc::build_tree(refs, cfg, exec::serial{});
    const std::size_t n = refs.size(), r = cfg.radius;
    check_topology(tree, n);
    // The references were permuted, not changed, and now follow the Morton curve.
    auto sorted_prims = refs.prim;
    std::sort(sorted_prims.begin(), sorted_prims.end());
    CHECK(std::equal(sorted_prims.begin(), sorted_prims.end(), original.begin(), original.end()));
    std::vector<std::uint32_t> keys(n);
    morton::codes<std::uint32_t>(refs, std::span<std::uint32_t>(keys), exec::serial{});
    CHECK(std::is_sorted(keys.begin(), keys.end()));

    auto dist = [&](std::size_t i, std::size_t j) { return merge(refs.box[i], refs.box[j]).half_area(); };
    std::vector<std::size_t> nn(n);
    for (std::size_t i = 0; i < n; ++i) {
        float best = std::numeric_limits<float>::infinity();
        for (std::size_t j = (i >= r ? i - r : 0); j <= std::min(n - 1, i + r); ++j)
            if (j != i && dist(i, j) < best) { best = dist(i, j); nn[i] = j; }
    }
    std::vector<std::pair<std::uint32_t, std::uint32_t>> expected;
    for (std::size_t i = 0; i < n; ++i)
        if (nn[nn[i]] == i && i < nn[i])
            expected.push_back({BinaryTree::leaf(std::uint32_t(i)), BinaryTree::leaf(std::uint32_t(nn[i]))});
    REQUIRE(!expected.empty());
    // The merge of leaves i < j is inner node j - 1 (the higher cluster's first leaf, minus one).
    for (const auto& pair : expected) {
        const std::uint32_t lower = BinaryTree::ref_of(pair.first), node = BinaryTree::ref_of(pair.second) - 1;
        CAPTURE(lower);
        CHECK(tree.left[node] == pair.first);
        CHECK(tree.right[node] == pair.second);
    }
}

/// PLOC written the plain way, serial, O(clusters * radius) per iteration, computing both directions of
/// every pair separately: the documented order of pairs is (merged half area, distance in positions,
/// parity of the lower position, lower position); mutual best pairs merge into node (first leaf of the
/// higher cluster) - 1; an iteration merging fewer than clusters / 64 pairs (or none) pairs up positions
/// (0,1), (2,3), ...
/// `n` right triangles growing with the index, each containing the one before.
std::vector<Trianglef> nested(int n) {
    std::vector<Trianglef> t;
    for (int i = 0; i < n; ++i) t.push_back({{-1.0f - i, -1.0f - i, 0}, {2.0f + 2 * i, -1.0f - i, 0}, {-1.0f - i, 2.0f + 2 * i, 0}});
    return t;
}

/// The clusters of the plain PLOCs below: tree ids, first leaves, boxes, in Morton order.
struct PlainClusters {
    std::vector<std::uint32_t> ids, first;
    std::vector<AABBf> boxes;
};

/// One plain PLOC iteration over `cl` (the order of pairs above; with `guard`, the adjacent pairing when
/// fewer than clusters / 64 merge). False when a merge's id is out of range or used twice.
bool plain_iteration(PlainClusters& cl, std::size_t radius, bool guard, BinaryTree& tree, std::vector<bool>& used) {
    const std::size_t c = cl.ids.size(), n = used.size() + 1;
    auto key = [&](std::size_t i, std::size_t j) {
        const std::size_t lo = std::min(i, j), hi = std::max(i, j);
        return std::make_tuple(merge(cl.boxes[lo], cl.boxes[hi]).half_area(), hi - lo, lo & 1, lo);
    };
    std::vector<std::size_t> nn(c);
    for (std::size_t i = 0; i < c; ++i) {
        std::size_t best = c;
        for (std::size_t j = (i >= radius ? i - radius : 0); j <= std::min(c - 1, i + radius); ++j)
            if (j != i && (best == c || key(i, j) < key(i, best))) best = j;
        nn[i] = best;
    }
    std::size_t merges = 0;
    for (std::size_t i = 0; i < c; ++i) merges += nn[nn[i]] == i && i < nn[i];
    if (guard && (merges == 0 || merges < c / 64))
        for (std::size_t i = 0; i < c; ++i) nn[i] = (i ^ 1) < c ? (i ^ 1) : i;
    PlainClusters next;
    for (std::size_t i = 0; i < c; ++i) {
        const std::size_t j = nn[i];
        const bool mutual = j != i && nn[j] == i;
        if (!mutual) {
            next.ids.push_back(cl.ids[i]);
            next.first.push_back(cl.first[i]);
            next.boxes.push_back(cl.boxes[i]);
            continue;
        }
        if (j < i) continue;
        const std::uint32_t node = cl.first[j] - 1;   // wraps around if first[j] == 0
        if (node >= n - 1 || used[node]) return false;
        used[node] = true;
        tree.left[node] = cl.ids[i];
        tree.right[node] = cl.ids[j];
        next.ids.push_back(node);
        next.first.push_back(cl.first[i]);
        next.boxes.push_back(merge(cl.boxes[i], cl.boxes[j]));
    }
    cl = std::move(next);
    return true;
}

/// A plain tree's start over `n` >= 2 references: every child slot unset, no id used.
BinaryTree plain_start(std::size_t n, std::vector<bool>& used) {
    BinaryTree tree;
    tree.left.assign(n - 1, BinaryTree::leaf_flag);
    tree.right.assign(n - 1, BinaryTree::leaf_flag);
    used.assign(n - 1, false);
    return tree;
}

/// The clusters that are references [b, e) themselves.
PlainClusters plain_leaves(const References<float>& sorted, std::size_t b, std::size_t e) {
    PlainClusters cl;
    for (std::size_t i = b; i < e; ++i) {
        cl.ids.push_back(BinaryTree::leaf(std::uint32_t(i)));
        cl.first.push_back(std::uint32_t(i));
        cl.boxes.push_back(sorted.box[i]);
    }
    return cl;
}

BinaryTree reference_ploc(const References<float>& sorted, std::size_t radius, bool& ids_ok) {
    ids_ok = true;
    const std::size_t n = sorted.size();
    BinaryTree tree;
    if (n == 0) return tree;
    if (n == 1) { tree.root = BinaryTree::leaf(0); return tree; }
    std::vector<bool> used;
    tree = plain_start(n, used);
    PlainClusters cl = plain_leaves(sorted, 0, n);
    while (cl.ids.size() > 1)
        if (!plain_iteration(cl, radius, true, tree, used)) { ids_ok = false; return tree; }
    tree.root = cl.ids[0];
    return tree;
}

/// H-PLOC written the plain way (serial recursion, copies): the radix tree of the sorted `keys` (a range
/// splits before the first key whose highest bit differing in the range is set, a range of equal keys in
/// its middle); a range of at most `limit` references gives those references as its clusters; otherwise
/// its clusters are its two halves', in order, merged by plain iterations (no guard) while more than
/// `limit` (at the root: 1) are left.
BinaryTree reference_hploc(const References<float>& sorted, const std::vector<std::uint32_t>& keys, std::size_t radius,
                           std::size_t limit, bool& ids_ok) {
    ids_ok = true;
    const std::size_t n = sorted.size();
    std::vector<bool> used;
    BinaryTree tree = plain_start(n, used);
    auto solve = [&](auto& self, std::size_t b, std::size_t e, std::size_t target) -> PlainClusters {
        PlainClusters cl;
        if (e - b <= limit) {
            cl = plain_leaves(sorted, b, e);
        } else {
            std::size_t m = b + (e - b) / 2;
            if (keys[b] != keys[e - 1]) {
                const int bit = 31 - std::countl_zero(keys[b] ^ keys[e - 1]);
                for (m = b; !((keys[m] >> bit) & 1u); ++m) {}
            }
            cl = self(self, b, m, limit);
            const PlainClusters r = self(self, m, e, limit);
            cl.ids.insert(cl.ids.end(), r.ids.begin(), r.ids.end());
            cl.first.insert(cl.first.end(), r.first.begin(), r.first.end());
            cl.boxes.insert(cl.boxes.end(), r.boxes.begin(), r.boxes.end());
        }
        while (ids_ok && cl.ids.size() > target) ids_ok = plain_iteration(cl, radius, false, tree, used);
        return cl;
    };
    tree.root = solve(solve, 0, n, 1).ids[0];
    return tree;
}

TEST_CASE("ploc: the original schedule's tree equals a plain serial PLOC, on every executor and radius") {
    const std::vector<std::pair<const char*, std::vector<Trianglef>>> scenes = {
        {"soup", random_soup(12000, 15)},
        {"flat", flat_scene(5000, 16)},
        {"identical", identical(3000)},
        {"nested", nested(3000)},
    };
    for (const auto& scene : scenes) {
        const std::string name = scene.first;
        const std::vector<Trianglef>& tris = scene.second;
        CAPTURE(name);
        for (std::uint32_t radius : {1u, 5u, 32u}) {
            CAPTURE(radius);
            auto sorted = make_references(std::span<const Trianglef>(tris), exec::serial{});
            morton::sort_references<std::uint32_t>(sorted, exec::serial{});
            bool ids_ok = false;
            const BinaryTree expected = reference_ploc(sorted, radius, ids_ok);
            REQUIRE(ids_ok);   // every merge got a fresh id in 0 .. n - 2
            for_each_executor([&](const auto& ex, const std::string& exec_name) {
                CAPTURE(exec_name);
                CHECK(same_tree(tree_of(tris, {.radius = radius, .subtree_clusters = 0}, ex), expected));
            });
        }
    }
}

TEST_CASE("ploc: the hierarchical schedule's tree equals a plain serial H-PLOC, on every executor, radius and limit") {
    const std::vector<std::pair<const char*, std::vector<Trianglef>>> scenes = {
        {"soup", random_soup(test::sanitized() ? 6000 : 20000, 15)},
        {"flat", flat_scene(5000, 16)},
        {"identical", identical(3000)},
        {"nested", nested(3000)},
        {"three", random_soup(3, 22)},
    };
    for (const auto& [name, tris] : scenes) {
        CAPTURE(name);
        auto sorted = make_references(std::span<const Trianglef>(tris), exec::serial{});
        const auto k = morton::sort_references<std::uint32_t>(sorted, exec::serial{});
        const std::vector<std::uint32_t> keys(k.begin(), k.end());
        for (std::uint32_t radius : {1u, 5u, 32u})
            for (std::uint32_t limit : {2u, 9u, 16u}) {
                CAPTURE(radius);
                CAPTURE(limit);
                bool ids_ok = false;
                const BinaryTree expected = reference_hploc(sorted, keys, radius, limit, ids_ok);
                REQUIRE(ids_ok);
                check_topology(expected, tris.size());
                for_each_executor([&](const auto& ex, const std::string& exec_name) {
                    CAPTURE(exec_name);
                    CHECK(same_tree(tree_of(tris, {.radius = radius, .subtree_clusters = limit}, ex), expected));
                }, true);
            }
    }
}

TEST_CASE("ploc: full builds are valid on every executor, node layout and primitive policy") {
    const std::vector<std::vector<Trianglef>> scenes = {
        random_soup(10000, 9), flat_scene(3000, 10),
        identical(2000), random_soup(1, 11), random_soup(2, 12), {}};
    for (const auto& tris : scenes) {
        CAPTURE(tris.size());
        const std::span<const Trianglef> span(tris);
        for_each_executor([&](const auto& ex, const std::string& name) {
            CAPTURE(name);
            const auto a = ploc::build(span, {}, ex);
            const auto ra = validate(a, span);
            CHECK_MESSAGE(ra.ok(), ra.summary());
            CHECK(a.primitive_count == tris.size());
            CHECK(a.empty() == tris.empty());
            const auto b = ploc::build<Node<>, prim::copied>(span, {.radius = 16, .morton_bits = 63}, ex);
            const auto rb = validate(b, span);
            CHECK_MESSAGE(rb.ok(), rb.summary());
        });
    }
    // Double precision nodes over double triangles.
    std::vector<Triangled> dtris;
    for (const auto& t : random_soup(5000, 13)) dtris.push_back({Vec3d(t.p0), Vec3d(t.p1), Vec3d(t.p2)});
    const auto d = ploc::build<Node<double, std::uint64_t>>(std::span<const Triangled>(dtris), {}, exec::serial{});
    const auto rd = validate(d, std::span<const Triangled>(dtris));
    CHECK_MESSAGE(rd.ok(), rd.summary());
}

TEST_CASE("ploc: the user's triangles are left untouched and bad triangles are counted") {
    auto tris = random_soup(5000, 14);
    tris[7].p0.y = std::numeric_limits<float>::quiet_NaN();
    const auto copy = tris;
    const auto bvh = ploc::build(std::span<const Trianglef>(tris), {}, exec::serial{});
    CHECK(bvh.excluded == 1);
    const auto rep = validate(bvh, std::span<const Trianglef>(tris));
    CHECK_MESSAGE(rep.ok(), rep.summary());
    CHECK(std::memcmp(tris.data(), copy.data(), tris.size() * sizeof(Trianglef)) == 0);
}

TEST_CASE("ploc: lower SAH than LBVH on the Stanford bunny, and a larger radius does not hurt") {
    const std::string path = test::data_path("meshes/bun_zipper.ply");
    if (!test::have_data("meshes/bun_zipper.ply")) {
        MESSAGE("skipping: " << path << " is absent");
        return;
    }
    const auto tris = io::read_ply(path).triangles();
    REQUIRE(tris.size() == 69451);
    const std::span<const Trianglef> span(tris);
    const double lbvh_sah = sah_cost(lbvh::build(span, {}, exec::serial{}));
    const auto p5 = ploc::build(span, {.radius = 5});
    const auto rep = validate(p5, span);
    CHECK_MESSAGE(rep.ok(), rep.summary());
    const double ploc5 = sah_cost(p5), ploc16 = sah_cost(ploc::build(span, {.radius = 16}));
    const double global5 = sah_cost(ploc::build(span, {.radius = 5, .subtree_clusters = 0}));
    MESSAGE("bunny SAH (Ct 3, Ci 2): lbvh " << lbvh_sah << ", ploc r=5 " << ploc5 << ", ploc r=16 " << ploc16
                                            << ", ploc r=5 original schedule " << global5);
    CHECK(ploc5 < lbvh_sah);
    CHECK(ploc16 <= ploc5 * 1.01);
    CHECK(ploc5 <= global5 * 1.03);   // the hierarchical schedule costs little tree quality
}

/// build, build_wide and build_blocks (references straight from the triangles, node facts made with the
/// nodes, blocks packed while the wide arrays are linked) against the plain path: make_references,
/// build_tree, compute_node_info + emission, make_wide_blocks; bit for bit.
TEST_CASE("ploc: build / build_wide / build_blocks are the plain path's trees, bit for bit, on every executor (4/8 wide, 4/8 lanes)") {
    // large enough for more than the 256 subtrees of the wide top (fewer under the sanitizers: still > 300 nodes)
    auto soup = random_soup(test::sanitized() ? 20000 : 40000, 17, 0.01f);
    for (std::size_t i = 11; i < soup.size(); i += 997) soup[i].p0.y = std::numeric_limits<float>::quiet_NaN();
    const std::vector<std::pair<const char*, std::vector<Trianglef>>> scenes = {
        {"soup with NaN", soup},   {"flat", flat_scene(3000, 18)}, {"identical", identical(2000)},
        {"one", random_soup(1, 19)}, {"two", random_soup(2, 20)},  {"nine", random_soup(9, 21)},
        {"empty", {}},
    };
    for (const auto& [name, tris] : scenes) {
        CAPTURE(name);
        const std::span<const Trianglef> ts(tris);
        for (const auto& [leaves, sub] : {std::pair{block_leaves, 8u}, std::pair{LeafConfig{}, 8u}, std::pair{block_leaves, 0u}, std::pair{LeafConfig{}, 16u}}) {
            CAPTURE(leaves.max_leaf_size);
            CAPTURE(sub);
            const ploc::Config cfg{.radius = 5, .subtree_clusters = sub, .leaves = leaves};
            const exec::serial s;
            // The plain path: make_references, build_tree (facts left to compute_node_info), then emission.
            auto refs = make_references(ts, s);
            const BinaryTree tree = ploc::build_tree(refs, cfg, s);
            const auto bin = emit_bvh<Node<>, prim::indexed>(tree, refs, ts, leaves, s);
            const auto w8 = emit_wide_bvh<8, Node<>, prim::indexed>(tree, refs, ts, leaves, s);
            const auto w4 = emit_wide_bvh<4, Node<>, prim::indexed>(tree, refs, ts, leaves, s);
            const auto b88 = make_wide_blocks(w8, ts, s);
            const auto b84 = make_wide_blocks<4>(w8, ts, s);
            const auto b44 = make_wide_blocks(w4, ts, s);
            if (tris.size() == soup.size()) REQUIRE(b88.nodes.size() > 300);
            for_each_executor([&](const auto& ex, const std::string& exec_name) {
                CAPTURE(exec_name);
                // build and build_wide (references from the triangles, facts made with the nodes) are that tree
                const auto b = ploc::build(ts, cfg, ex);
                CHECK((b.nodes.size() == bin.nodes.size() && b.prim_ids == bin.prim_ids && b.depth == bin.depth &&
                       b.excluded == bin.excluded && b.primitive_count == bin.primitive_count &&
                       (b.nodes.empty() || std::memcmp(b.nodes.data(), bin.nodes.data(), b.nodes.size() * sizeof(b.nodes[0])) == 0)));
                const auto w = ploc::build_wide<8>(ts, cfg, ex);
                CHECK((w.nodes.size() == w8.nodes.size() && w.prim_ids == w8.prim_ids && w.depth == w8.depth &&
                       (w.nodes.empty() || std::memcmp(w.nodes.data(), w8.nodes.data(), w.nodes.size() * sizeof(w.nodes[0])) == 0)));
                CHECK(test::block_difference(ploc::build_blocks(ts, cfg, ex), b88) == "");
                CHECK(test::block_difference(ploc::build_blocks<8, 4>(ts, cfg, ex), b84) == "");
                CHECK(test::block_difference(ploc::build_blocks<4>(ts, cfg, ex), b44) == "");
            });
            const auto direct = ploc::build_blocks(ts, cfg);
            CHECK(sah_cost(direct) == sah_cost(w8));   // the same tree: the same SAH, to the bit
            CHECK(direct.primitive_count == tris.size());
        }
    }
}
