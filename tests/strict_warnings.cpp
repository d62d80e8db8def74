// Instantiates the public templates as a user's code does, so that a compile of this file under strict
// warning flags (-Wconversion -Wsign-conversion -Wshadow ... -Werror; tests/strict_warnings.cmake) sees
// the warnings a user who adds dynbvh as source would see. Compiled only (never run): every call sits in
// a function that is not called. Compile with and without -fopenmp and -DDYNBVH_WITH_TBB=1.
#include <dynbvh/aabb.hpp>
#include <dynbvh/binned_sah.hpp>
#include <dynbvh/bvh.hpp>
#include <dynbvh/cost.hpp>
#include <dynbvh/executor.hpp>
#include <dynbvh/intersect.hpp>
#include <dynbvh/io/bart.hpp>
#include <dynbvh/io/frames.hpp>
#include <dynbvh/io/obj.hpp>
#include <dynbvh/io/ply.hpp>
#include <dynbvh/io/scene.hpp>
#include <dynbvh/kbvh.hpp>
#include <dynbvh/lbvh.hpp>
#include <dynbvh/mesh.hpp>
#include <dynbvh/morton_wide.hpp>
#include <dynbvh/node.hpp>
#include <dynbvh/packet.hpp>
#include <dynbvh/ploc.hpp>
#include <dynbvh/presplit.hpp>
#include <dynbvh/ray.hpp>
#include <dynbvh/refit.hpp>
#include <dynbvh/sah.hpp>
#include <dynbvh/traverse.hpp>
#include <dynbvh/traverse_wide.hpp>
#include <dynbvh/triangle.hpp>
#include <dynbvh/validate.hpp>
#include <dynbvh/vec.hpp>
#include <dynbvh/version.hpp>
#include <dynbvh/wide.hpp>
#include <dynbvh/wide_blocks.hpp>
#include <dynbvh/dynamic.hpp>
#include <dynbvh/two_level.hpp>

#include <cstdint>
#include <span>
#include <string>
#include <type_traits>
#include <vector>

namespace strict {

using namespace dynbvh;

// Every query on a binary tree and on its 4- and 8-wide forms, with both traversal policies.
template <class NodeT, class Prim, class Exec>
double queries(Bvh<NodeT, Prim>& bvh, std::span<const Triangle<typename NodeT::scalar_type>> tris, const Exec& ex) {
    using T = typename NodeT::scalar_type;
    const Ray<T> ray{.org = {0, 0, 10}, .dir = {0, 0, -1}};
    double sum = 0;
    refit(bvh, tris, ex);
    sum += double(intersect<trace::robust>(bvh, tris, ray).t) + double(occluded<trace::robust>(bvh, tris, ray));
    sum += double(intersect<trace::fast>(bvh, tris, ray).t) + double(occluded<trace::fast>(bvh, tris, ray));
    sum += double(intersect<trace::policy<box::fast, tri::watertight>>(bvh, tris, ray).t);
    sum += double(validate(bvh, tris).ok());
    sum += sah_cost(bvh, {}, ex) + epo(bvh, tris, {}, ex);
    auto w4 = make_wide<4>(bvh, ex);
    auto w8 = make_wide<8>(Bvh<NodeT, Prim>(bvh), ex);
    refit(w4, tris, ex);
    refit(w8, tris, ex);
    sum += sah_cost(w4, {}, ex) + sah_cost(w8, {}, ex);
    sum += double(intersect<trace::robust>(w4, tris, ray).t) + double(occluded<trace::robust>(w4, tris, ray));
    sum += double(intersect<trace::fast>(w4, tris, ray).t) + double(occluded<trace::fast>(w4, tris, ray));
    sum += double(intersect<trace::robust>(w8, tris, ray).t) + double(occluded<trace::robust>(w8, tris, ray));
    sum += double(intersect<trace::fast>(w8, tris, ray).t) + double(occluded<trace::fast>(w8, tris, ray));
    // Packets of 8 and 16 (packet.hpp) on the wide forms.
    RayPacket<T, 8> p8;
    RayPacket<T, 16> p16;
    p8.set(0, ray);
    p16.set(3, ray);
    sum += double(intersect<trace::robust>(w8, tris, p8).t[0]) + double(occluded<trace::robust>(w8, tris, p16, 0x0f0fu));
    sum += double(intersect<trace::fast>(w4, tris, p16, all_lanes<16>, {.min_rays = 2}).t[3]) + double(occluded<trace::fast>(w4, tris, p8));
    sum += double(intersect<trace::policy<box::robust, tri::moller_trumbore>>(w4, tris, p8).hit(0).t);
    sum += double(brute_force_intersect<trace::robust, T>(tris, ray).t);
    sum += double(brute_force_occluded<trace::fast, T>(tris, ray));
    return sum;
}

// Every builder for one node type, executor and primitive policy, each tree through every query.
template <class N, class Prim, class Exec>
double builders(const std::vector<Triangle<typename N::scalar_type>>& tris, const Exec& ex) {
    using T = typename N::scalar_type;
    const std::span<const Triangle<T>> s(tris);
    double sum = 0;
    auto a = lbvh::build<N, Prim>(s, {}, ex);
    sum += queries(a, s, ex);
    auto b = ploc::build<N, Prim>(s, {.radius = 5}, ex);
    sum += queries(b, s, ex);
    auto c = kbvh::build<N, Prim>(s, kbvh::Config<kbvh::with_ploc>{}, ex);
    sum += queries(c, s, ex);
    auto d = kbvh::build<N, Prim>(s, kbvh::Config<kbvh::with_lbvh>{}, ex);
    sum += queries(d, s, ex);
    auto e = kbvh::build<N, Prim>(s, kbvh::Config<kbvh::with_binned_sah>{}, ex);
    sum += queries(e, s, ex);
    auto f = binned_sah::build<N, Prim>(s, {}, ex);
    sum += queries(f, s, ex);
    // Direct wide emission, every builder, 4 and 8 wide.
    sum += double(lbvh::build_wide<8, N, Prim>(s, {}, ex).nodes.size() + lbvh::build_wide<4, N, Prim>(s, {}, ex).nodes.size());
    sum += double(ploc::build_wide<8, N, Prim>(s, {.radius = 5}, ex).nodes.size() + ploc::build_wide<4, N, Prim>(s, {}, ex).nodes.size());
    sum += double(kbvh::build_wide<8, N, Prim>(s, kbvh::Config<kbvh::with_ploc>{}, ex).nodes.size() +
                  kbvh::build_wide<4, N, Prim>(s, kbvh::Config<kbvh::with_lbvh>{}, ex).nodes.size() +
                  kbvh::build_wide<8, N, Prim>(s, kbvh::Config<kbvh::with_binned_sah>{}, ex).nodes.size());
    sum += double(binned_sah::build_wide<8, N, Prim>(s, {}, ex).nodes.size() + binned_sah::build_wide<4, N, Prim>(s, {}, ex).nodes.size());
    // The wide tree straight from the Morton codes, queried and refitted.
    auto m8 = morton_wide::build<8, N, Prim>(s, {}, ex);
    auto m4 = morton_wide::build<4, N, Prim>(s, {.morton_bits = 63, .max_leaf_size = 4}, ex);
    refit(m8, s, ex);
    sum += double(intersect(m8, s, Ray<T>{.org = {0, 0, 10}, .dir = {0, 0, -1}}).t) + double(occluded(m4, s, Ray<T>{.org = {0, 0, 10}, .dir = {0, 0, -1}}));
    sum += double(morton_wide::build(tris, {}, ex).nodes.size());
    // The std::vector overloads (node type from the triangles).
    sum += double(lbvh::build(tris, {}, ex).nodes.size() + ploc::build(tris, {}, ex).nodes.size() +
                  kbvh::build(tris, {}, ex).nodes.size() + binned_sah::build(tris, {}, ex).nodes.size());
    return sum;
}

// SIMD triangle-block leaves (float only): both lane counts, both traversal policies.
template <class Exec>
double blocks(std::span<const Trianglef> tris, const Exec& ex) {
    const Rayf ray{.org = {0, 0, 10}, .dir = {0, 0, -1}};
    const auto bvh = ploc::build(tris, {.leaves = block_leaves}, ex);
    const auto b8 = make_wide_blocks<8>(bvh, tris, ex);
    const auto b84 = make_wide_blocks<8, 4>(bvh, tris, ex);
    double sum = double(intersect<trace::robust>(b8, tris, ray).t) + double(occluded<trace::fast>(b8, tris, ray));
    sum += double(intersect<trace::fast>(b84, tris, ray).t) + double(occluded<trace::robust>(b84, tris, ray));
    RayPacket<float, 16> p;
    p.set(0, ray);
    sum += double(intersect(b8, tris, p).t[0]) + double(occluded(b84, tris, p));
    sum += double(intersect<trace::policy<box::robust, tri::moller_trumbore>>(b8, tris, p).hit_mask());
    RayPacket<float, 8> q;
    sum += double(occluded<trace::policy<box::robust, tri::moller_trumbore>>(b84, tris, q, 0x3u));
    RayPacket<float, 32> r32;
    r32.set(31, ray);
    sum += double(intersect(b8, tris, r32).t[31]) + double(occluded(b8, tris, r32, 0x80000001u));
    // packed straight from a wide tree, and refitted in place
    auto mb = make_wide_blocks(morton_wide::build<8>(tris, {}, ex), tris, ex);
    auto md = morton_wide::build_blocks(tris, {}, ex);   // the same tree in one step
    auto md4 = morton_wide::build_blocks<4>(tris, {.morton_bits = 63, .max_leaf_size = 4}, ex);
    sum += double(intersect(md, tris, ray).t) + double(occluded<trace::fast>(md4, tris, ray));
    auto mb4 = make_wide_blocks<4>(lbvh::build_wide<8>(tris, {.leaves = block_leaves}, ex), tris, ex);
    refit(mb, tris, ex);
    refit(mb4, tris, ex);
    sum += double(intersect(mb, tris, ray).t) + double(occluded(mb4, tris, ray));
    return sum;
}

// The refit-or-rebuild policy and two-level scenes over the default builder.
template <class Exec>
double dynamic_scenes(std::span<const Trianglef> tris, const Exec& ex) {
    Dynamic<builder::ploc, Node<>, prim::indexed, Exec> dyn({}, ex);
    const FrameReport r = dyn.update(tris);
    return r.sah_after + double(dyn.bvh().nodes.size());
}

// Indexed meshes read in place (mesh.hpp): every builder, wide build, refit, traversal, blocks and Dynamic.
template <class N, class Prim, class Index, class Exec>
double meshes(const MeshView<typename N::scalar_type, Index>& mesh, const Exec& ex) {
    using T = typename N::scalar_type;
    const Ray<T> ray{.org = {0, 0, 10}, .dir = {0, 0, -1}};
    auto a = lbvh::build<N, Prim>(mesh, {}, ex);
    auto b = ploc::build<N, Prim>(mesh, {}, ex);
    auto c = kbvh::build<N, Prim>(mesh, kbvh::Config<kbvh::with_lbvh>{}, ex);
    auto d = binned_sah::build<N, Prim>(mesh, {}, ex);
    auto w = ploc::build_wide<8, N, Prim>(mesh, {}, ex);
    auto w4 = lbvh::build_wide<4, N, Prim>(mesh, {}, ex);
    double sum = double(kbvh::build_wide<8, N, Prim>(mesh, {}, ex).nodes.size() +
                        binned_sah::build_wide<4, N, Prim>(mesh, {}, ex).nodes.size());
    refit(a, mesh, ex);
    refit(w, mesh, ex);
    sum += double(intersect(a, mesh, ray).t) + double(occluded<trace::fast>(b, mesh, ray)) + double(intersect(c, mesh, ray).t);
    sum += double(intersect(w, mesh, ray).t) + double(occluded(w4, mesh, ray)) + double(d.nodes.size());
    Dynamic<builder::lbvh, N, Prim, Exec> dyn({}, ex);
    sum += dyn.update(mesh).sah_after;
    sum += double(morton_wide::build<8, N, Prim>(mesh, {}, ex).nodes.size() + morton_wide::build<4>(mesh).nodes.size());
    if constexpr (std::is_same_v<T, float>) {
        auto blocks = make_wide_blocks<8>(b, mesh, ex);
        sum += double(intersect<trace::fast>(blocks, mesh, ray).t);
        refit(blocks, mesh, ex);
        auto straight = make_wide_blocks(morton_wide::build<8, N, Prim>(mesh, {}, ex), mesh, ex);
        sum += double(occluded(straight, mesh, ray));
        sum += double(intersect(morton_wide::build_blocks(mesh, {}, ex), mesh, ray).t);
    }
    sum += double(ploc::build(mesh).nodes.size() + mesh.stride() + mesh.indices().size() + mesh.vertex_count());
    sum += double(mesh.vertex(0).x) + double(mesh[0].p0.x) + double(mesh.empty());
    return sum;
}

template <class Exec>
double all(const Exec& ex) {
    double sum = 0;
    sum += builders<Node<float>, prim::indexed>({}, ex);
    sum += builders<Node<float>, prim::copied>({}, ex);
    sum += builders<Node<double>, prim::indexed>({}, ex);
    sum += builders<Node<double>, prim::copied>({}, ex);
    sum += builders<Node<double, std::uint64_t>, prim::indexed>({}, ex);
    sum += blocks(std::span<const Trianglef>(), ex);
    sum += dynamic_scenes(std::span<const Trianglef>(), ex);
    sum += meshes<Node<float>, prim::indexed>(MeshView<float>(), ex);
    sum += meshes<Node<float>, prim::copied>(MeshView<float, std::uint16_t>(), ex);
    sum += meshes<Node<double>, prim::indexed>(MeshView<double>(), ex);
    return sum;
}

double everything() {
    double sum = all(exec::serial{});
#if defined(_OPENMP)
    sum += all(exec::omp{});
#endif
#if defined(DYNBVH_WITH_TBB)
    sum += all(exec::tbb{});
#endif
    sum += all(exec::default_executor{});

    // Triangles from indexed vertices.
    const std::vector<Vec3f> vf;
    const std::vector<Vec3d> vd;
    const std::vector<std::uint32_t> i32;
    const std::vector<std::size_t> i64;
    const std::vector<int> isigned;
    sum += double(make_triangles<float, std::uint32_t>(vf, i32).size() + make_triangles<double, std::size_t>(vd, i64).size() +
                  make_triangles<float, int>(vf, isigned).size());

    // Two-level scenes (two_level.hpp): single rays and packets, float and double.
    TwoLevel<> tl;
    const std::vector<Triangle<float>> one(1);
    tl.add_object(one);
    tl.commit();
    const RayPacket<float, 16> tp16;
    const RayPacket<float, 8> tp8;
    sum += double(tl.intersect(Ray<float>{}).t) + double(tl.intersect(tp16).hit(0).instance) + double(tl.occluded(tp8, 0x3u));
    sum += double(tl.intersect<trace::fast>(tp8).t[1]) + double(tl.occluded<trace::fast>(tp16));
    TwoLevel<builder::lbvh, Node<double>> td;
    const RayPacket<double, 8> dp;
    sum += double(td.intersect(dp).t[0]) + double(td.occluded(dp)) + double(td.occluded(Ray<double>{}));

    // The loaders.
    std::string warnings;
    const io::Mesh m = io::read_mesh("scene.ply", &warnings);
    sum += double(m.triangles().size()) + double(io::read_ply("a.ply").faces.size()) +
           double(io::read_obj("a.obj").faces.size());
    auto frames = io::open_frames("frames/", {});
    io::Frame fr;
    frames->frame(0, fr);
    sum += double(frames->frame_count()) + double(io::list_frames("frames/").size());
    auto bart = io::load_bart("scene.aff");
    bart->evaluate(0.5, fr);
    bart->evaluate(0.5, fr, exec::serial{});
    bart->update(0.6, fr);
    bart->update(0.6, fr, exec::serial{});
#if defined(_OPENMP)
    bart->evaluate(0.5, fr, exec::omp{});
    bart->update(0.6, fr, exec::omp{});
#endif
#if defined(DYNBVH_WITH_TBB)
    bart->evaluate(0.5, fr, exec::tbb{});
    bart->update(0.6, fr, exec::tbb{});
#endif
    sum += double(io::load_bart_from_string("v\n", "m.aff", io::bart_file_map_resolver({}))->triangle_count());
    return sum;
}

} // namespace strict

// Every member of the value types.
template struct dynbvh::Vec3<float>;
template struct dynbvh::Vec3<double>;
template struct dynbvh::AABB<float>;
template struct dynbvh::AABB<double>;
template struct dynbvh::Triangle<float>;
template struct dynbvh::Triangle<double>;
template class dynbvh::MeshView<float>;
template class dynbvh::MeshView<float, std::uint16_t>;
template class dynbvh::MeshView<double>;
template struct dynbvh::Ray<float>;
template struct dynbvh::Ray<double>;
template struct dynbvh::Hit<float>;
template struct dynbvh::Hit<double>;
template struct dynbvh::Node<float>;
template struct dynbvh::Node<double>;
template struct dynbvh::Node<double, std::uint64_t>;
template struct dynbvh::WideNode<float, std::uint32_t, 4>;
template struct dynbvh::WideNode<float, std::uint32_t, 8>;
template struct dynbvh::WideNode<double, std::uint32_t, 4>;
template struct dynbvh::WideNode<double, std::uint64_t, 8>;

// Keeps everything() from being discarded as unused (it is never called).
double (*strict_warnings_entry)() = &strict::everything;
