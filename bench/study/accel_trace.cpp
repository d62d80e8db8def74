// The study's traversal code (accel_impl::Trees, see dyn_accel.hpp), compiled once for both primitive
// policies and every executor.
#include "dyn_accel.hpp"

#include <type_traits>

#include <dynbvh/packet.hpp>
#include <render/whitted.hpp>

namespace dynbvh::study::accel_impl {

namespace {

/// f.template operator()<Policy>() with the spec's box and triangle tests.
template <class F>
decltype(auto) with_policy(const BuilderSpec& spec, const F& f) {
    if (spec.fast_box && spec.fast_tri) return f.template operator()<trace::fast>();
    if (spec.fast_box) return f.template operator()<trace::policy<box::fast, tri::watertight>>();
    if (spec.fast_tri) return f.template operator()<trace::policy<box::robust, tri::moller_trumbore>>();
    return f.template operator()<trace::robust>();
}

/// f(tree) with the tree spec.wide names: the 4- or 8-wide one (with block leaves when spec.blocks), or
/// the binary one for wide=0.
template <class Prim, class F>
decltype(auto) with_tree(const BuilderSpec& spec, const Trees<Prim>& t, const F& f) {
    if (spec.blocks && spec.wide == 8) return f(t.view8 ? *t.view8 : t.blocks8);
    if (spec.blocks && spec.wide == 4) return f(t.view4 ? *t.view4 : t.blocks4);
    if (spec.wide == 8) return f(t.wide8);
    if (spec.wide == 4) return f(t.wide4);
    return f(t.bvh);
}

} // namespace

template <class Prim>
void Trees<Prim>::trace(const BuilderSpec& spec, const Backend& backend, std::span<const Trianglef> tris, const RayGen& gen,
                        std::span<std::uint32_t> out) const {
    with_policy(spec, [&]<class Policy>() {
        with_tree(spec, *this, [&](const auto& tree) {
            using Tree = std::remove_cvref_t<decltype(tree)>;
            if constexpr (requires { Tree::width; }) {   // wide trees: packets of primary_packet_rays (packet.hpp) unless --rays single
                if (spec.packets) {
                    constexpr int N = primary_packet_rays;
                    trace_tiles_ray_packets<N>(backend, gen, out, [&](const RayPacket<float, N>& p, std::uint32_t active, std::uint32_t* prims) {
                        const HitPacket<float, N> h = dynbvh::intersect<Policy>(tree, tris, p, active);
                        for (int k = 0; k < N; ++k) prims[k] = h.prim[k];
                    });
                    return;
                }
            }
            trace_tiles(backend, gen, out, [&](const Rayf& r) { return dynbvh::intersect<Policy>(tree, tris, r).prim; });
        });
    });
}

template <class Prim>
Hitf Trees<Prim>::intersect(const BuilderSpec& spec, std::span<const Trianglef> tris, const Rayf& r) const {
    return with_policy(spec, [&]<class Policy>() {
        return with_tree(spec, *this, [&](const auto& tree) { return dynbvh::intersect<Policy>(tree, tris, r); });
    });
}

template <class Prim>
bool Trees<Prim>::occluded(const BuilderSpec& spec, std::span<const Trianglef> tris, const Rayf& r) const {
    return with_policy(spec, [&]<class Policy>() {
        return with_tree(spec, *this, [&](const auto& tree) { return dynbvh::occluded<Policy>(tree, tris, r); });
    });
}

template <class Prim>
void Trees<Prim>::intersect_packet(const BuilderSpec& spec, std::span<const Trianglef> tris, std::span<const Rayf> rays,
                                   std::span<Hitf> out) const {
    with_policy(spec, [&]<class Policy>() {
        with_tree(spec, *this, [&](const auto& tree) {
            using Tree = std::remove_cvref_t<decltype(tree)>;
            if constexpr (requires { Tree::width; }) {
                if (spec.packets) return render::intersect_packet<Policy>(tree, tris, rays, out);
            }
            for (std::size_t k = 0; k < rays.size(); ++k) out[k] = dynbvh::intersect<Policy>(tree, tris, rays[k]);
        });
    });
}
template <class Prim>
void Trees<Prim>::occluded_packet(const BuilderSpec& spec, std::span<const Trianglef> tris, std::span<const Rayf> rays,
                                  std::span<std::uint8_t> out) const {
    with_policy(spec, [&]<class Policy>() {
        with_tree(spec, *this, [&](const auto& tree) {
            using Tree = std::remove_cvref_t<decltype(tree)>;
            if constexpr (requires { Tree::width; }) {
                if (spec.packets) return render::occluded_packet<Policy>(tree, tris, rays, out);
            }
            for (std::size_t k = 0; k < rays.size(); ++k) out[k] = dynbvh::occluded<Policy>(tree, tris, rays[k]) ? 1 : 0;
        });
    });
}
template <class Prim>
std::size_t Trees<Prim>::memory_bytes(const BuilderSpec& spec) const {
    return with_tree(spec, *this, [](const auto& tree) { return tree.memory_bytes(); });
}

template struct Trees<prim::indexed>;
template struct Trees<prim::copied>;

} // namespace dynbvh::study::accel_impl
