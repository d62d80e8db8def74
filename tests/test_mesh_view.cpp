// MeshView (mesh.hpp): every builder, wide build, block packing, refit, traversal and Dynamic over an
// indexed mesh read in place gives, bit for bit, what the same call gives over the flattened
// make_triangles span; bad views throw std::invalid_argument naming the argument.
#include "support.hpp"

#include <cmath>
#include <cstring>
#include <limits>
#include <stdexcept>
#include <string>
#include <type_traits>
#include <vector>

#include <dynbvh/binned_sah.hpp>
#include <dynbvh/builder.hpp>
#include <dynbvh/dynamic.hpp>
#include <dynbvh/kbvh.hpp>
#include <dynbvh/lbvh.hpp>
#include <dynbvh/mesh.hpp>
#include <dynbvh/morton_wide.hpp>
#include <dynbvh/ploc.hpp>
#include <dynbvh/refit.hpp>
#include <dynbvh/traverse.hpp>
#include <dynbvh/traverse_wide.hpp>
#include <dynbvh/wide.hpp>
#include <dynbvh/wide_blocks.hpp>

using namespace dynbvh;
using namespace dynbvh::test;

namespace {

/// A vertex with attributes interleaved after the position (32 bytes): the strided case.
struct FatVertex {
    float pos[3];
    float normal[3];
    float uv[2];
};
static_assert(sizeof(FatVertex) == 32);

/// An indexed mesh owned by the test, with its flattened triangles for the span path.
struct Mesh {
    std::string name;
    std::vector<Vec3f> vertices;
    std::vector<std::uint32_t> indices;
    std::vector<std::uint16_t> indices16;   // the same indices, when every index fits
    std::vector<FatVertex> fat;             // the same positions, interleaved with attributes

    void finish() {
        indices16.clear();
        bool fits = true;
        for (std::uint32_t i : indices) fits = fits && i <= 0xffffu;
        if (fits)
            for (std::uint32_t i : indices) indices16.push_back(std::uint16_t(i));
        fat.resize(vertices.size());
        for (std::size_t i = 0; i < vertices.size(); ++i)
            fat[i] = {{vertices[i].x, vertices[i].y, vertices[i].z}, {1, 2, 3}, {float(i), -1}};
    }
    std::vector<Trianglef> flat() const {
        return make_triangles(std::span<const Vec3f>(vertices), std::span<const std::uint32_t>(indices));
    }
    MeshView<float> view() const { return {std::span<const Vec3f>(vertices), std::span<const std::uint32_t>(indices)}; }
    MeshView<float, std::uint16_t> view16() const {
        return {std::span<const Vec3f>(vertices), std::span<const std::uint16_t>(indices16)};
    }
    MeshView<float> strided() const {
        return {fat.data(), fat.size(), sizeof(FatVertex), std::span<const std::uint32_t>(indices)};
    }
};

/// UV sphere with shared vertices: (stacks + 1) * slices vertices, 2 * stacks * slices triangles.
Mesh sphere_mesh(int stacks, int slices) {
    Mesh m;
    m.name = "sphere " + std::to_string(stacks) + "x" + std::to_string(slices);
    for (int i = 0; i <= stacks; ++i)
        for (int j = 0; j < slices; ++j) {
            const double th = std::numbers::pi * i / stacks, ph = 2 * std::numbers::pi * j / slices;
            m.vertices.push_back({float(std::sin(th) * std::cos(ph)), float(std::cos(th)), float(std::sin(th) * std::sin(ph))});
        }
    const auto id = [&](int i, int j) { return std::uint32_t(i * slices + (j % slices)); };
    for (int i = 0; i < stacks; ++i)
        for (int j = 0; j < slices; ++j) {
            m.indices.insert(m.indices.end(), {id(i, j), id(i + 1, j), id(i + 1, j + 1)});
            m.indices.insert(m.indices.end(), {id(i, j), id(i + 1, j + 1), id(i, j + 1)});
        }
    m.finish();
    return m;
}

/// A random soup as an indexed mesh: 3 vertices per triangle, indices in a shuffled order.
Mesh soup_mesh(std::size_t n, std::uint64_t seed) {
    Mesh m;
    m.name = "soup " + std::to_string(n);
    for (const Trianglef& t : random_soup(n, seed)) m.vertices.insert(m.vertices.end(), {t.p0, t.p1, t.p2});
    std::vector<std::uint32_t> perm(m.vertices.size());
    for (std::size_t i = 0; i < perm.size(); ++i) perm[i] = std::uint32_t(i);
    Rng r(seed + 1);
    for (std::size_t i = perm.size(); i > 1; --i) std::swap(perm[i - 1], perm[r.next() % i]);
    std::vector<Vec3f> shuffled(m.vertices.size());
    for (std::size_t i = 0; i < perm.size(); ++i) shuffled[perm[i]] = m.vertices[i];
    for (std::size_t i = 0; i < perm.size(); ++i) m.indices.push_back(perm[i]);
    m.vertices = shuffled;
    m.finish();
    return m;
}

std::vector<Mesh> meshes() {
    std::vector<Mesh> out;
    out.push_back(sanitized() ? sphere_mesh(24, 48) : sphere_mesh(64, 128));   // 16384 triangles, 8320 shared vertices
    out.push_back(soup_mesh(sanitizer_scaled(12000), 5));
    Mesh bad = sphere_mesh(16, 32);
    bad.name = "sphere with non-finite vertices";
    bad.vertices[3].x = std::numeric_limits<float>::quiet_NaN();
    bad.vertices[40].y = std::numeric_limits<float>::infinity();
    bad.vertices[41].z = -std::numeric_limits<float>::infinity();
    bad.finish();
    out.push_back(bad);
    Mesh empty;
    empty.name = "empty";
    empty.vertices = {{0, 0, 0}, {1, 0, 0}};   // vertices, no triangle
    empty.finish();
    out.push_back(empty);
    Mesh one = sphere_mesh(1, 3);
    one.name = "three triangles";
    out.push_back(one);
    return out;
}

template <class A, class B>
bool same_bits(const A& a, const B& b) {
    static_assert(sizeof(A) == sizeof(B));
    return std::memcmp(&a, &b, sizeof(A)) == 0;
}

/// Empty when `a` and `b` are the same tree to the bit (binary, wide or block leaves), else the first difference.
template <class Tree>
std::string difference(const Tree& a, const Tree& b) {
    if (a.nodes.size() != b.nodes.size())
        return "node counts " + std::to_string(a.nodes.size()) + " and " + std::to_string(b.nodes.size());
    for (std::size_t i = 0; i < a.nodes.size(); ++i)
        if (!same_bits(a.nodes[i], b.nodes[i])) return "node " + std::to_string(i) + " differs";
    if (a.prim_ids.size() != b.prim_ids.size()) return "prim_ids sizes differ";
    for (std::size_t s = 0; s < a.prim_ids.size(); ++s)
        if (a.prim_ids[s] != b.prim_ids[s]) return "prim_ids[" + std::to_string(s) + "] differs";
    if (a.leaf_triangles.size() != b.leaf_triangles.size()) return "leaf_triangles sizes differ";
    for (std::size_t s = 0; s < a.leaf_triangles.size(); ++s)
        if (!same_bits(a.leaf_triangles[s], b.leaf_triangles[s])) return "leaf triangle " + std::to_string(s) + " differs";
    if constexpr (Tree::block_lanes > 0) {
        if (a.blocks.size() != b.blocks.size()) return "block counts differ";
        for (std::size_t k = 0; k < a.blocks.size(); ++k)   // field by field: the blocks have padding bytes
            if (!same_bits(a.blocks[k].v, b.blocks[k].v) || !same_bits(a.blocks[k].prim, b.blocks[k].prim) ||
                a.blocks[k].count != b.blocks[k].count)
                return "block " + std::to_string(k) + " differs";
    }
    if (a.depth != b.depth) return "depth " + std::to_string(a.depth) + " and " + std::to_string(b.depth);
    if (a.primitive_count != b.primitive_count || a.excluded != b.excluded) return "counts differ";
    return {};
}

/// Calls check(name, build) with `build(source)` giving the tree of every builder: build when Output
/// is 0, else build_wide<Output>.
// (a macro: the builders are namespaces, not types)
#define MESH_VIEW_BUILDER(name, ns, cfg)                                                                  \
    check(name, [&](auto s) {                                                                            \
        if constexpr (Output == 0) return dynbvh::ns::build<Node<>, Prim>(s, cfg, ex);                  \
        else return dynbvh::ns::build_wide<Output, Node<>, Prim>(s, cfg, ex);                           \
    })
template <int Output, class Prim, class Exec, class Check>
void for_each_builder(const Exec& ex, Check&& check) {
    MESH_VIEW_BUILDER("lbvh30", lbvh, dynbvh::lbvh::Config{.morton_bits = 30});
    MESH_VIEW_BUILDER("lbvh63", lbvh, dynbvh::lbvh::Config{.morton_bits = 63});
    MESH_VIEW_BUILDER("ploc", ploc, dynbvh::ploc::Config{});
    MESH_VIEW_BUILDER("kbvh", kbvh, dynbvh::kbvh::Config<>{.split = {.beta = 0.3f}});   // presplit: many fragments
    MESH_VIEW_BUILDER("binned_sah", binned_sah, dynbvh::binned_sah::Config{});
}
#undef MESH_VIEW_BUILDER

template <int Output, class Prim, class Exec>
void compare_builds(const Mesh& m, const Exec& ex) {
    const std::vector<Trianglef> flat = m.flat();
    const std::span<const Trianglef> span(flat);
    for_each_builder<Output, Prim>(ex, [&](const char* builder, auto&& build) {
        CAPTURE(builder);
        const auto want = build(span);
        CHECK(want.primitive_count == flat.size());
        CHECK(difference(build(m.view()), want) == "");
        CHECK(difference(build(m.strided()), want) == "");
        // (16-bit indices: in sanitized builds with the binary copied pair only, CI time; the other pairs
        // read them through the same MeshView code)
        if constexpr (!sanitized_build || (Output == 0 && std::is_same_v<Prim, prim::copied>))
            if (!m.indices16.empty()) CHECK(difference(build(m.view16()), want) == "");
        if constexpr (Output == 0) {
            // Block packing of that tree, from the view and from the span.
            if constexpr (std::is_same_v<Prim, prim::indexed>) {
                const auto blocks = make_wide_blocks<8>(want, span, ex);
                CHECK(difference(make_wide_blocks<8>(want, m.view(), ex), blocks) == "");
                CHECK(difference(make_wide_blocks<8>(want, m.strided(), ex), blocks) == "");
                const auto blocks4 = make_wide_blocks<4>(want, span, ex);
                CHECK(difference(make_wide_blocks<4>(want, m.view(), ex), blocks4) == "");
            }
        }
    });
}

/// Rays from outside towards the mesh's box, a few of them through vertices (ties on shared edges).
std::vector<Rayf> rays_for(const Mesh& m, std::size_t n) {
    Rng r(11);
    std::vector<Rayf> rays;
    for (std::size_t i = 0; i < n; ++i) {
        const Vec3f o{r.uniform(-3, 3), r.uniform(-3, 3), 3};
        Vec3f target{r.uniform(-1, 1), r.uniform(-1, 1), r.uniform(-1, 1)};
        if (i % 5 == 0 && !m.vertices.empty()) target = m.vertices[r.next() % m.vertices.size()];
        rays.push_back({.org = o, .dir = target - o});
    }
    return rays;
}

template <class Tree, class View>
void compare_traversal(const Tree& tree, std::span<const Trianglef> flat, const View& view, const std::vector<Rayf>& rays) {
    for (const Rayf& ray : rays) {
        const Hit<float> want = intersect(tree, flat, ray);
        const Hit<float> got = intersect(tree, view, ray);
        REQUIRE(same_bits(got, want));
        const Hit<float> brute = brute_force_intersect<trace::robust, float>(flat, ray);
        CHECK(got.t == brute.t);   // same t to the bit (traverse.hpp's exactness contract)
        CHECK(occluded(tree, view, ray) == occluded(tree, flat, ray));
        CHECK(occluded<trace::fast>(tree, view, ray) == occluded<trace::fast>(tree, flat, ray));
        CHECK(same_bits(intersect<trace::fast>(tree, view, ray), intersect<trace::fast>(tree, flat, ray)));
    }
}

/// Moves every vertex in place (a wave), in both the packed and the strided buffer.
void move_vertices(Mesh& m, float phase) {
    for (std::size_t i = 0; i < m.vertices.size(); ++i) {
        Vec3f& v = m.vertices[i];
        v.x += 0.05f * std::sin(3.0f * v.y + phase);
        v.z += 0.03f * std::cos(2.0f * v.x - phase);
        std::memcpy(m.fat[i].pos, &v, sizeof(v));
    }
}

std::string what_of(auto&& f) {
    try {
        f();
    } catch (const std::invalid_argument& e) {
        return e.what();
    }
    return "(no std::invalid_argument)";
}

} // namespace

TEST_CASE("mesh view: reads the triangles make_triangles gives, with any stride and index width") {
    const Mesh m = sphere_mesh(8, 16);
    const auto flat = m.flat();
    const auto v = m.view();
    const auto v16 = m.view16();
    const auto vs = m.strided();
    REQUIRE(v.size() == flat.size());
    REQUIRE(v16.size() == flat.size());
    REQUIRE(vs.size() == flat.size());
    CHECK(vs.stride() == 32);
    CHECK(v.vertex_count() == m.vertices.size());
    for (std::size_t k = 0; k < flat.size(); ++k) {
        CHECK(same_bits(v[k], flat[k]));
        CHECK(same_bits(v16[k], flat[k]));
        CHECK(same_bits(vs[k], flat[k]));
    }
    const MeshView<float> none;
    CHECK(none.empty());
    CHECK(none.size() == 0);
    // Nothing the view reads is written.
    const Mesh again = sphere_mesh(8, 16);
    CHECK(std::memcmp(m.vertices.data(), again.vertices.data(), m.vertices.size() * sizeof(Vec3f)) == 0);
    // Double-precision meshes build Node<double> trees.
    std::vector<Vec3d> vd;
    for (const Vec3f& p : m.vertices) vd.push_back({p.x, p.y, p.z});
    const MeshView<double> md(std::span<const Vec3d>(vd), std::span<const std::uint32_t>(m.indices));
    const auto flatd = make_triangles(std::span<const Vec3d>(vd), std::span<const std::uint32_t>(m.indices));
    const Bvh<Node<double>> bd = ploc::build(md);
    CHECK(difference(bd, ploc::build(flatd)) == "");
}

/// Calls f(mesh, executor) for every test mesh and executor.
template <class F>
void for_each_mesh_and_executor(F&& f) {
    const auto all = meshes();
    for_each_executor([&](auto ex) {
        CAPTURE(executor_name<decltype(ex)>());
        for (const Mesh& m : all) {
            CAPTURE(m.name);
            f(m, ex);
        }
    });
}

TEST_CASE("mesh view: every builder gives the span's tree, bit for bit (binary, 4- and 8-wide, blocks)") {
    // Each output with each primitive layout where the layout changes the code: the binary emission
    // with both, the wide emission once per width with each layout (CI time: not all four pairs). Each
    // pair runs on one executor: OpenMP the 8-wide indexed one and TBB the binary copied one, so that the
    // view is read from parallel chunks on both paths, the serial executor the other two (and those of a
    // backend this build lacks). Builders give the same tree on every executor (tested on spans), so
    // each pair's view == span holds on every executor.
    for_each_mesh_and_executor([](const Mesh& m, auto ex) {
        using E = decltype(ex);
        constexpr bool serial = std::is_same_v<E, exec::serial>;
        if constexpr (std::is_same_v<E, exec::tbb> || (serial && !has_executor<exec::tbb>)) compare_builds<0, prim::copied>(m, ex);
        if constexpr ((!serial && !std::is_same_v<E, exec::tbb>) || (serial && !has_executor<exec::omp>)) compare_builds<8, prim::indexed>(m, ex);
        // (sanitized builds: the binary copied and 8-wide indexed pairs only, which read the view on
        // both paths; the other two read it through the same code, and test_emit_wide runs their
        // emission there; CI time)
        if constexpr (serial && !sanitized_build) {
            compare_builds<0, prim::indexed>(m, ex);
            compare_builds<4, prim::copied>(m, ex);
        }
    });
}

TEST_CASE("mesh view: morton_wide and block packing of wide trees give the span's trees") {
    for_each_mesh_and_executor([](const Mesh& m, auto ex) {
        const auto flat = m.flat();
        const std::span<const Trianglef> span(flat);
        const auto w8 = morton_wide::build<8, Node<>, prim::indexed>(span, {}, ex);
        CHECK(difference(morton_wide::build<8, Node<>, prim::indexed>(m.view(), {}, ex), w8) == "");
        CHECK(difference(morton_wide::build<8, Node<>, prim::indexed>(m.strided(), {}, ex), w8) == "");
        const auto w4 = morton_wide::build<4, Node<>, prim::copied>(span, {.morton_bits = 63}, ex);
        CHECK(difference(morton_wide::build<4, Node<>, prim::copied>(m.view(), {.morton_bits = 63}, ex), w4) == "");
        if (!m.indices16.empty())
            CHECK(difference(morton_wide::build<4, Node<>, prim::copied>(m.view16(), {.morton_bits = 63}, ex), w4) == "");
        // Blocks straight from a wide tree (the traced layout), from the view and from the span.
        const auto blocks = make_wide_blocks(w8, span, ex);
        CHECK(difference(make_wide_blocks(w8, m.view(), ex), blocks) == "");
        // The traced layout in one step (morton_wide::build_blocks), from the view: the span's packed tree.
        CHECK(difference(morton_wide::build_blocks(m.view(), {}, ex), blocks) == "");
        CHECK(difference(morton_wide::build_blocks(m.strided(), {}, ex), blocks) == "");
        CHECK(difference(morton_wide::build_blocks(span, {}, ex), blocks) == "");
        const auto pw = ploc::build_wide<8, Node<>, prim::indexed>(m.view(), {.leaves = block_leaves}, ex);
        CHECK(difference(make_wide_blocks<4>(pw, m.strided(), ex), make_wide_blocks<4>(pw, span, ex)) == "");
    });
}

TEST_CASE("mesh view: refit of block trees in place equals the span's") {
    Mesh m = sphere_mesh(32, 64);
    const exec::serial ex;
    auto flat = m.flat();
    auto from_view = make_wide_blocks(ploc::build_wide<8, Node<>, prim::indexed>(m.view(), {.leaves = block_leaves}, ex), m.view(), ex);
    auto from_span = make_wide_blocks(ploc::build_wide<8, Node<>, prim::indexed>(flat, {.leaves = block_leaves}, ex), flat, ex);
    REQUIRE(difference(from_view, from_span) == "");
    for (int frame = 1; frame <= 2; ++frame) {
        move_vertices(m, float(frame));
        flat = m.flat();
        refit(from_view, m.strided(), ex);
        refit(from_span, std::span<const Trianglef>(flat), ex);
        CHECK(difference(from_view, from_span) == "");
    }
    CHECK(what_of([&] { refit(from_view, sphere_mesh(4, 4).view(), ex); }).find("dynbvh::refit:") == 0);
}

TEST_CASE("mesh view: builder policies (builder.hpp) take views") {
    const Mesh m = sphere_mesh(16, 32);
    const auto flat = m.flat();
    const exec::serial ex;
    CHECK(difference(builder::ploc::build<Node<>, prim::indexed>(m.view(), {}, ex),
                     builder::ploc::build<Node<>, prim::indexed>(std::span<const Trianglef>(flat), {}, ex)) == "");
    CHECK(difference(builder::lbvh::build<Node<>, prim::copied>(m.view16(), {}, ex),
                     builder::lbvh::build<Node<>, prim::copied>(flat, {}, ex)) == "");
    CHECK(difference(builder::binned_sah::build<Node<>, prim::indexed>(m.strided(), {}, ex),
                     builder::binned_sah::build<Node<>, prim::indexed>(std::span<const Trianglef>(flat), {}, ex)) == "");
}

TEST_CASE("mesh view: traversal through the view equals the span's and brute force") {
    for (const Mesh& m : meshes()) {
        CAPTURE(m.name);
        const auto flat = m.flat();
        const std::span<const Trianglef> span(flat);
        const auto rays = rays_for(m, sanitizer_scaled(300));
        const exec::serial ex;
        const auto bi = ploc::build<Node<>, prim::indexed>(m.view(), {.leaves = block_leaves}, ex);
        const auto bc = ploc::build<Node<>, prim::copied>(m.view(), {}, ex);
        compare_traversal(bi, span, m.view(), rays);
        compare_traversal(bi, span, m.strided(), rays);
        compare_traversal(bc, span, m.view(), rays);
        if (!m.indices16.empty()) compare_traversal(bi, span, m.view16(), rays);
        compare_traversal(make_wide<8>(bi, ex), span, m.view(), rays);
        compare_traversal(make_wide<4>(bc, ex), span, m.view(), rays);
        compare_traversal(make_wide_blocks<8>(bi, m.view(), ex), span, m.view(), rays);
        compare_traversal(make_wide_blocks<8, 4>(bi, m.strided(), ex), span, m.strided(), rays);
        // A kbvh tree (fragments: a triangle in several leaves).
        compare_traversal(kbvh::build<Node<>, prim::indexed>(m.view(), {.split = {.beta = 0.3f}}, ex), span, m.view(), rays);
    }
}

TEST_CASE("mesh view: refit (binary and wide) after moving vertices in place equals the span's") {
    Mesh m = sphere_mesh(32, 64);
    for_each_executor([&](auto ex) {
        CAPTURE(executor_name<decltype(ex)>());
        auto flat = m.flat();
        auto bi_v = lbvh::build<Node<>, prim::indexed>(m.view(), {}, ex);
        auto bc_v = ploc::build<Node<>, prim::copied>(m.strided(), {}, ex);
        auto wi_v = ploc::build_wide<8, Node<>, prim::indexed>(m.view16(), {}, ex);
        auto wc_v = lbvh::build_wide<4, Node<>, prim::copied>(m.view(), {}, ex);
        auto bi_s = lbvh::build<Node<>, prim::indexed>(std::span<const Trianglef>(flat), {}, ex);
        auto bc_s = ploc::build<Node<>, prim::copied>(std::span<const Trianglef>(flat), {}, ex);
        auto wi_s = ploc::build_wide<8, Node<>, prim::indexed>(std::span<const Trianglef>(flat), {}, ex);
        auto wc_s = lbvh::build_wide<4, Node<>, prim::copied>(std::span<const Trianglef>(flat), {}, ex);
        for (int frame = 1; frame <= 3; ++frame) {
            CAPTURE(frame);
            move_vertices(m, float(frame));
            flat = m.flat();
            const std::span<const Trianglef> span(flat);
            refit(bi_v, m.view(), ex);
            refit(bc_v, m.strided(), ex);
            refit(wi_v, m.view16(), ex);
            refit(wc_v, m.view(), ex);
            refit(bi_s, span, ex);
            refit(bc_s, span, ex);
            refit(wi_s, span, ex);
            refit(wc_s, span, ex);
            CHECK(difference(bi_v, bi_s) == "");
            CHECK(difference(bc_v, bc_s) == "");
            CHECK(difference(wi_v, wi_s) == "");
            CHECK(difference(wc_v, wc_s) == "");
            CHECK(validate(bi_v, span).ok());
        }
    });
}

TEST_CASE("mesh view: Dynamic::update with a view makes the span's decisions and trees") {
    for (const bool async : {false, true}) {
        CAPTURE(async);
        Mesh m = sphere_mesh(32, 64);
        using D = Dynamic<builder::ploc, Node<>, prim::indexed, exec::serial>;
        D over_view({.rebuild_threshold = 1.02, .async = async});
        D over_span({.rebuild_threshold = 1.02, .async = async});
        const MeshView<float> view = m.view();   // one view for all frames: the vertices move under it
        int rebuilds = 0;
        for (int frame = 0; frame < 8; ++frame) {
            CAPTURE(frame);
            if (frame > 0) move_vertices(m, float(frame));
            const auto flat = m.flat();
            if (async) {   // the same frames see the background rebuild finished
                over_view.wait_for_rebuild();
                over_span.wait_for_rebuild();
            }
            const FrameReport a = over_view.update(view);
            const FrameReport b = over_span.update(std::span<const Trianglef>(flat));
            CHECK(a.decision == b.decision);
            CHECK(a.reason == b.reason);
            CHECK(same_bits(a.sah_after, b.sah_after));
            rebuilds += a.decision != Decision::refit;
            CHECK(difference(over_view.bvh(), over_span.bvh()) == "");
        }
        CHECK(rebuilds >= 2);   // the first frame, and at least one for SAH growth
    }
}

TEST_CASE("mesh view: bad buffers throw std::invalid_argument naming the argument") {
    const Mesh m = sphere_mesh(4, 8);
    const auto vspan = std::span<const Vec3f>(m.vertices);
    // Index out of range.
    std::vector<std::uint32_t> idx = m.indices;
    idx[3 * 17 + 1] = std::uint32_t(m.vertices.size() + 960);
    CHECK(what_of([&] { (void)MeshView<float>(vspan, std::span<const std::uint32_t>(idx)); }) ==
          "dynbvh::MeshView: mesh indices: triangle 17 has vertex index " + std::to_string(m.vertices.size() + 960) +
              " >= vertex count " + std::to_string(m.vertices.size()));
    std::vector<std::uint16_t> idx16 = m.indices16;
    idx16.back() = std::uint16_t(m.vertices.size());
    CHECK(what_of([&] { (void)MeshView<float, std::uint16_t>(vspan, std::span<const std::uint16_t>(idx16)); })
              .find("mesh indices: triangle " + std::to_string(idx16.size() / 3 - 1) + " has vertex index") != std::string::npos);
    // Index count not a multiple of 3.
    CHECK(what_of([&] { (void)MeshView<float>(vspan, std::span<const std::uint32_t>(m.indices.data(), 7)); }) ==
          "dynbvh::MeshView: index count 7 is not a multiple of 3");
    // Strides.
    CHECK(what_of([&] { (void)MeshView<float>(m.fat.data(), m.fat.size(), 8, std::span<const std::uint32_t>(m.indices)); }) ==
          "dynbvh::MeshView: stride 8 bytes is less than one vertex (3 * sizeof(T) = 12 bytes)");
    CHECK(what_of([&] { (void)MeshView<float>(m.fat.data(), m.fat.size(), 14, std::span<const std::uint32_t>(m.indices)); }) ==
          "dynbvh::MeshView: stride 14 bytes is not a multiple of alignof(T) = 4");
    CHECK(what_of([&] {
              (void)MeshView<float>(reinterpret_cast<const std::byte*>(m.fat.data()) + 2, m.fat.size() - 1, 32,
                              std::span<const std::uint32_t>(m.indices));
          }) == "dynbvh::MeshView: vertices is not aligned to alignof(T) = 4 bytes");
    CHECK(what_of([&] {
              (void)MeshView<float>(m.fat.data(), std::numeric_limits<std::size_t>::max() / 16, 32, std::span<const std::uint32_t>(m.indices));
          }).find("overflows") != std::string::npos);
    // Null pointers with nonzero counts.
    CHECK(what_of([&] { (void)MeshView<float>(nullptr, 5, 12, m.indices.data(), 3); }) ==
          "dynbvh::MeshView: vertices is null but vertex_count is 5");
    CHECK(what_of([&] { (void)MeshView<float>(m.vertices.data(), m.vertices.size(), 12, static_cast<const std::uint32_t*>(nullptr), 6); }) ==
          "dynbvh::MeshView: indices is null but the index count is 6");
    // Null with zero counts is an empty mesh, and builds an empty tree.
    const MeshView<float> empty(nullptr, 0, 12, static_cast<const std::uint32_t*>(nullptr), 0);
    CHECK(empty.empty());
    CHECK(ploc::build(empty).empty());
    // Nothing the user passed was modified by the failed constructions.
    const Mesh again = sphere_mesh(4, 8);
    CHECK(std::memcmp(m.vertices.data(), again.vertices.data(), m.vertices.size() * sizeof(Vec3f)) == 0);
    CHECK(m.indices == again.indices);
}

TEST_CASE("mesh view: a view of another triangle count throws and leaves the tree unchanged") {
    const Mesh m = sphere_mesh(8, 16), other = sphere_mesh(8, 17);
    auto bvh = ploc::build(m.view());
    auto wide = ploc::build_wide<8>(m.view());
    const auto bvh0 = ploc::build(m.view());
    const auto wide0 = ploc::build_wide<8>(m.view());
    const Rayf ray{.org = {0, 0, 5}, .dir = {0, 0, -1}};
    CHECK(what_of([&] { refit(bvh, other.view()); }).find("dynbvh::refit: 272 triangles were passed (span or mesh view) but the tree was built over 256") == 0);
    CHECK(what_of([&] { refit(wide, other.view()); }).find("dynbvh::refit:") == 0);
    CHECK(what_of([&] { (void)intersect(bvh, other.view(), ray); }).find("dynbvh::intersect:") == 0);
    CHECK(what_of([&] { (void)occluded(wide, other.view(), ray); }).find("dynbvh::occluded:") == 0);
    CHECK(what_of([&] { (void)make_wide_blocks<8>(bvh, other.view()); }).find("dynbvh::make_wide_blocks:") == 0);
    CHECK(difference(bvh, bvh0) == "");
    CHECK(difference(wide, wide0) == "");
    // Dynamic: a bad view cannot be made, so the policy never sees it; its tree stays as it was.
    Dynamic<> dyn;
    dyn.update(m.view());
    std::vector<std::uint32_t> idx = m.indices;
    idx[0] = 100000;
    CHECK_THROWS_AS((void)dyn.update(MeshView<float>(std::span<const Vec3f>(m.vertices), std::span<const std::uint32_t>(idx))),
                    std::invalid_argument);
    CHECK(dyn.frames() == 1);
    CHECK(difference(dyn.bvh(), bvh0) == "");
}
