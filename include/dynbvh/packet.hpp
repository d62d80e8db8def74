// SPDX-License-Identifier: MIT
/// @file packet.hpp
/// Closest-hit and any-hit queries of packets of 8, 16 or 32 rays against a `WideBvh` (Wald, Slusallek,
/// Benthin, Wagner 2001, "Interactive Rendering with Coherent Ray Tracing"; Benthin, Wald, Woop, Ernst,
/// Mark 2012, "Combining Single and Packet-Ray Tracing for Arbitrary Ray Distributions on the Intel MIC
/// Architecture"):
/// @code
///   dynbvh::RayPacket<float, 8> p;                       // e.g. a 4x2 tile of camera rays
///   for (int k = 0; k < 8; ++k) p.set(k, camera_ray(k));
///   auto hits = dynbvh::intersect(wide, tris, p);          // lane k == intersect(wide, tris, p.ray(k))
///   std::uint32_t occ = dynbvh::occluded(wide, tris, p, 0x0f);   // lanes 0..3 only
/// @endcode
///
/// Contract: every active lane (bit k of `active` set) gets, bit for bit, what the single-ray query on
/// the same tree gives its ray (traverse_wide.hpp): t, u, v, prim, hit or miss, for every ray, NaN and
/// empty intervals included. Inactive lanes get the miss value (Hit{}: t = +inf, u = v = 0, prim =
/// invalid_prim) from `intersect` and a 0 bit from `occluded`. This holds because the single-ray answer
/// does not depend on the order in which boxes are visited: box::robust never culls a box holding the
/// closest hit, and an exact tie goes to the larger triangle index (detail::replaces_hit). (Where
/// tri::watertight's documented distance limit is exceeded - triangles smaller than about 1e-6 of their
/// distance from the origin, intersect.hpp - a hit can lie outside its box by rounding; the single-ray
/// answer then depends on the visit order, as a binary and a wide tree can disagree, and so can a packet.)
///
/// Traversal (float trees, box::robust, with SSE; detail::PacketTraversal): the packet's set-up is SIMD
/// across its rays (validity, reciprocal directions, octants, dominant axes); the triangle test's
/// shear waits for a group's first leaf, and its per-ray set-up for a ray's first candidate. The
/// active rays are grouped by direction octant (and, for tri::watertight, dominant axis); a group of at least `PacketConfig::min_rays` rays
/// is traced as one packet, the others ray by ray. A coherent group (no direction component exactly 0)
/// tests the W child boxes of an inner node for all its rays at once by interval arithmetic over the
/// group's origins and reciprocal directions (one SIMD test per node, conservative: every box any of its
/// rays hits passes) and enters the inner children with all its rays; leaf boxes are tested ray by ray
/// (SIMD across rays, box::robust's operations), and only the rays that hit a leaf's box test its
/// triangles. Other groups (and PacketConfig::interval = false) test every child box ray by ray, keep a
/// ray mask and per-ray entry distances per stack entry, and once fewer than `min_rays` rays remain in a
/// subtree each finishes it with the single-ray traversal from that node (Benthin et al.'s hybrid;
/// detail::wide_traverse_octant). Children are visited nearest first (the packet's nearest entry), and
/// stack entries are skipped once none of their rays can find a closer hit there.
/// Leaves: block leaves (prim::blocks) and index leaves test each triangle against all rays of the
/// packet at once: tri::watertight with the SIMD float filter of the block test (detail::WatertightFilter,
/// the same forward error bound per (ray, triangle) pair) and the exact test on each kept ray with that
/// ray's tmax (a block's filters all run before its exact tests, in the block's order; with AVX, four
/// kept rays at once where three or four of four neighbouring lanes are kept: the scalar test's
/// operations in SIMD, the same bits). With AVX-512 (packets of 16 and 32): the kept rays of a
/// triangle, eight at a time, gathered into one 8-lane double exact test (exact8); for closest hits on
/// blocks of eight, the whole block at once (test_block): per 16-lane step the filter runs triangle by
/// triangle when the step holds more rays than the block has triangles, else two rays at a time
/// against the block's eight triangles, and the kept (ray, triangle) pairs of all triangles go through
/// the exact test eight at a time, in the order the scalar loop would take them;
/// tri::moller_trumbore with the scalar test's operations lane by lane (bit for bit as long as neither
/// side is FMA-contracted, as for the block test).
/// SIMD width: packets of 16 take one AVX-512 step per operation where the compiler targets AVX-512F
/// (detail::Lanes16, unless DYNBVH_NO_AVX512), else two AVX steps (or four SSE ones); packets of 32 take
/// two such steps, packets of 8 AVX (or SSE) steps. The answers do not depend on it. Packets of 32 (an
/// 8x4 tile as two 4x4 halves, lanes 0-15 and 16-31) share each node's interval test and each
/// triangle's set-up among twice the rays: on coherent primary rays they are the fastest (bench_trace's
/// x32 rows).
/// Other cases (double trees, box::fast, -DDYNBVH_NO_SIMD, non-x86): a loop of single-ray queries, which
/// gives the same answers by construction. (box::fast is not conservative, so its answers could depend
/// on the visit order: its packets are traced ray by ray.)
/// State: each traced lane's closest hit so far lives in the result packet itself (no per-group set-up
/// or copy-out of hits).
/// Cost: no allocation unless the tree is deeper than 32 wide levels (then one heap stack per packet).
/// Measured (bench_trace, primary rays, 8-wide block trees): see the README / the bench's packet rows.
#pragma once

#include <algorithm>
#include <bit>
#include <cstddef>
#include <cstdint>
#include <limits>
#include <new>
#include <span>
#include <type_traits>
#include <vector>

#include "detail/check_triangles.hpp"
#include "detail/exact_lanes.hpp"
#include "detail/simd.hpp"
#include "detail/triangle_block.hpp"
#include "intersect.hpp"
#include "ray.hpp"
#include "traverse.hpp"
#include "traverse_wide.hpp"
#include "wide.hpp"
#include "wide_blocks.hpp"

namespace dynbvh {

/// N rays, structure of arrays (N = 8, 16 or 32; 64-byte aligned): lane k is the ray
/// org = (org_x[k], org_y[k], org_z[k]), dir = (dir_x[k], dir_y[k], dir_z[k]), [tmin[k], tmax[k]], with
/// Ray's conventions. A default packet holds N default rays (Ray<T>{}).
template <class T, int N>
struct alignas(64) RayPacket {
    static_assert(N == 8 || N == 16 || N == 32, "dynbvh: ray packets have 8, 16 or 32 rays");
    static_assert(std::is_same_v<T, float> || std::is_same_v<T, double>, "dynbvh: scalar must be float or double");
    /// Rays per packet.
    static constexpr int size = N;
    /// @{
    /// Origins, per lane.
    alignas(64) T org_x[std::size_t(N)], org_y[std::size_t(N)], org_z[std::size_t(N)];
    /// @}
    /// @{
    /// Directions, per lane (need not be normalised).
    alignas(64) T dir_x[std::size_t(N)], dir_y[std::size_t(N)], dir_z[std::size_t(N)];
    /// @}
    /// @{
    /// Hit intervals [tmin, tmax], per lane.
    alignas(64) T tmin[std::size_t(N)], tmax[std::size_t(N)];
    /// @}

    /// N default rays.
    RayPacket() noexcept {
        for (int k = 0; k < N; ++k) set(k, Ray<T>{});
    }
    /// Stores `r` in lane k (0 <= k < N).
    void set(int k, const Ray<T>& r) noexcept {
        const std::size_t i = std::size_t(k);
        org_x[i] = r.org.x;
        org_y[i] = r.org.y;
        org_z[i] = r.org.z;
        dir_x[i] = r.dir.x;
        dir_y[i] = r.dir.y;
        dir_z[i] = r.dir.z;
        tmin[i] = r.tmin;
        tmax[i] = r.tmax;
    }
    /// The ray of lane k (0 <= k < N), bit for bit as stored.
    Ray<T> ray(int k) const noexcept {
        const std::size_t i = std::size_t(k);
        return {{org_x[i], org_y[i], org_z[i]}, {dir_x[i], dir_y[i], dir_z[i]}, tmin[i], tmax[i]};
    }
};

/// The closest hits of a packet, structure of arrays, with Hit's conventions per lane (a miss: t = +inf,
/// u = v = 0, prim = invalid_prim). A default HitPacket is all misses.
template <class T, int N>
struct alignas(64) HitPacket {
    static_assert(N == 8 || N == 16 || N == 32, "dynbvh: ray packets have 8, 16 or 32 rays");
    /// Rays per packet.
    static constexpr int size = N;
    /// Distance along each lane's ray (multiples of |dir|); +inf for a miss.
    alignas(64) T t[std::size_t(N)];
    /// @{
    /// Barycentrics of p1 and p2 per lane (Hit's convention); 0 for a miss.
    alignas(64) T u[std::size_t(N)], v[std::size_t(N)];
    /// @}
    /// The hit triangle's index per lane, or invalid_prim.
    alignas(64) std::uint32_t prim[std::size_t(N)];

    /// All misses.
    HitPacket() noexcept {
        for (int k = 0; k < N; ++k) set(k, Hit<T>{});
    }
    /// Stores `h` in lane k.
    void set(int k, const Hit<T>& h) noexcept {
        const std::size_t i = std::size_t(k);
        t[i] = h.t;
        u[i] = h.u;
        v[i] = h.v;
        prim[i] = h.prim;
    }
    /// Lane k's hit.
    Hit<T> hit(int k) const noexcept {
        const std::size_t i = std::size_t(k);
        return {t[i], u[i], v[i], prim[i]};
    }
    /// Bit k set when lane k hit something.
    std::uint32_t hit_mask() const noexcept {
        std::uint32_t m = 0;
        for (int k = 0; k < N; ++k) m |= prim[std::size_t(k)] != invalid_prim ? std::uint32_t(1) << k : 0u;
        return m;
    }
};

/// Run-time knobs of the packet traversal.
struct PacketConfig {
    /// A group of rays sharing a direction octant (and dominant axis) is traced as a packet while at
    /// least this many of its rays are active in a subtree; below it each finishes the subtree with the
    /// single-ray traversal. Default 3 (bunny primary rays in 4x4 packets, 8-wide block tree, interval
    /// = false, instructions per packet relative to 3: 1 +1%, 2 +0%, 5 +2%; interval = true is 25%
    /// fewer); 1 keeps packets to the leaves, N + 1 traces every ray alone. Answers do not depend on it.
    unsigned min_rays = 3;
    /// Coherent groups (no direction component exactly 0) traverse inner nodes with one interval test
    /// per node for the whole group (bounds of the group's origins and reciprocal directions, as in
    /// Wald et al. 2007, "Ray Tracing Deformable Scenes using Dynamic Bounding Volume Hierarchies"),
    /// and test leaf boxes ray by ray; false tests every child box ray by ray. Default true (faster on
    /// primary rays). Answers do not depend on it.
    bool interval = true;
};

/// The mask of all N lanes.
template <int N>
inline constexpr std::uint32_t all_lanes = N >= 32 ? ~std::uint32_t(0) : (std::uint32_t(1) << N) - 1u;

namespace detail {

/// The single-ray query for one lane (the reference the packet reproduces).
template <class Policy, bool AnyHit, class WN, class P, class S = typename WN::scalar_type>
DYNBVH_ALWAYS_INLINE Hit<S> single_lane(const WideBvh<WN, P>& bvh, std::span<const Triangle<S>> tris, const Ray<S>& r) {
    return wide_traverse<Policy, AnyHit>(bvh, tris, r);
}

#if defined(DYNBVH_SSE)

/// Horizontal minimum of one register.
DYNBVH_ALWAYS_INLINE float hmin(__m128 x) noexcept {
    x = _mm_min_ps(x, _mm_shuffle_ps(x, x, 0x4e));
    x = _mm_min_ps(x, _mm_shuffle_ps(x, x, 0xb1));
    return _mm_cvtss_f32(x);
}
#if defined(DYNBVH_AVX)
DYNBVH_ALWAYS_INLINE float hmin(__m256 x) noexcept {
    return hmin(_mm_min_ps(_mm256_castps256_ps128(x), _mm256_extractf128_ps(x, 1)));
}
#endif

/// Horizontal maximum of one register.
DYNBVH_ALWAYS_INLINE float hmax(__m128 x) noexcept {
    x = _mm_max_ps(x, _mm_shuffle_ps(x, x, 0x4e));
    x = _mm_max_ps(x, _mm_shuffle_ps(x, x, 0xb1));
    return _mm_cvtss_f32(x);
}
#if defined(DYNBVH_AVX)
DYNBVH_ALWAYS_INLINE float hmax(__m256 x) noexcept {
    return hmax(_mm_max_ps(_mm256_castps256_ps128(x), _mm256_extractf128_ps(x, 1)));
}
#endif

/// Lanes of `m` set -> a, else b.
DYNBVH_ALWAYS_INLINE __m128 select(__m128 m, __m128 a, __m128 b) noexcept { return _mm_or_ps(_mm_and_ps(m, a), _mm_andnot_ps(m, b)); }
#if defined(DYNBVH_AVX)
DYNBVH_ALWAYS_INLINE __m256 select(__m256 m, __m256 a, __m256 b) noexcept { return _mm256_blendv_ps(b, a, m); }
#endif
#if defined(DYNBVH_AVX512)
DYNBVH_ALWAYS_INLINE __m512 select(__mmask16 m, __m512 a, __m512 b) noexcept { return _mm512_mask_blend_ps(m, b, a); }
/// Eight lanes of x, the lower (H = 0) or upper (H = 1) ones. (The zero-masked form: in GCC 12 the
/// unmasked extract, which _mm512_castps512_ps256 uses too, trips -Wuninitialized.)
template <int H>
DYNBVH_ALWAYS_INLINE __m256 half8(__m512 x) noexcept {
    return _mm256_castpd_ps(_mm512_maskz_extractf64x4_pd(__mmask8(0xff), _mm512_castps_pd(x), H));
}
DYNBVH_ALWAYS_INLINE float hmin(__m512 x) noexcept { return hmin(_mm256_min_ps(half8<0>(x), half8<1>(x))); }
DYNBVH_ALWAYS_INLINE float hmax(__m512 x) noexcept { return hmax(_mm256_max_ps(half8<0>(x), half8<1>(x))); }

#endif

#if defined(DYNBVH_AVX512)
/// The lanes of a packet of N rays: one AVX-512 step for 16, else AVX (or SSE) steps.
template <int N>
using packet_lanes = std::conditional_t<N % 16 == 0, Lanes16, lanes_for<8>>;
#else
template <int N>
using packet_lanes = lanes_for<8>;
#endif

/// One stack entry of the packet traversal: a node (count 0) or leaf slot, the rays that entered its
/// box and their entry distances.
template <class I, int N>
struct alignas(64) PacketEntry {
    float tentry[std::size_t(N)];
    I child;
    I count;
    std::uint32_t mask;
};

/// Triangle sources of PacketTraversal::test_triangle: lane j of a block, read in place ...
template <int L>
struct BlockLane {
    const TriangleBlock<L>& b;
    int j;
    DYNBVH_ALWAYS_INLINE float c(int vertex, std::size_t axis) const noexcept { return b.v[vertex][axis][j]; }
    DYNBVH_ALWAYS_INLINE Triangle<float> get() const noexcept { return b.triangle(j); }
};
/// ... or a whole triangle.
struct WholeTriangle {
    const Triangle<float>& t;
    DYNBVH_ALWAYS_INLINE float c(int vertex, std::size_t axis) const noexcept { return (vertex == 0 ? t.p0 : vertex == 1 ? t.p1 : t.p2)[axis]; }
    DYNBVH_ALWAYS_INLINE Triangle<float> get() const noexcept { return t; }
};

/// One stack entry of the interval traversal: a node or leaf slot, the rays it is for and a lower
/// bound of their entry distances.
template <class I>
struct IntervalEntry {
    I child;
    I count;
    std::uint32_t mask;
    float tentry;
};

/// The packet traversal of one group of rays sharing a direction octant Oct (and, for tri::watertight,
/// the dominant axis): float WideBvh, box::robust, triangle policy Tri. Each lane keeps the state of
/// the single-ray traversal (tmax, best triangle, hit); the result of lane k is what that traversal
/// gives its ray (see the file comment).
template <class Tri, bool AnyHit, class WN, class P, int N>
struct PacketTraversal {
    using V = packet_lanes<N>;   // AVX-512 for 16 rays where compiled in, else AVX, else SSE
    using R = typename V::reg;
    using I = typename WN::index_type;
    static constexpr int W = WN::width;
    static constexpr int NS = N / V::n;   // SIMD steps per packet
    static constexpr std::size_t NZ = std::size_t(N), WZ = std::size_t(W);   // (array bounds)
    static constexpr std::uint32_t step_lanes = (std::uint32_t(1) << V::n) - 1u;   // one SIMD step's lanes
    using WB = WideBvh<WN, P>;
    using Policy = trace::policy<box::robust, Tri>;
    using TriPrepared = typename Tri::template prepared<float>;
    using Entry = PacketEntry<I, N>;
    static constexpr std::size_t fixed_levels = 32;
    static constexpr std::size_t fixed_cap = std::size_t(W - 1) * fixed_levels + 1;

    const WB& bvh;
    std::span<const Triangle<float>> tris;
    const RayPacket<float, N>& pk;   // origins, directions and tmin are read from the packet itself
    HitPacket<float, N>& res;        // each lane's closest hit so far (all misses on entry), its answer at the end
    unsigned min_rays;
    bool interval;
    // per-lane state (lanes outside the current group hold whatever; every test is masked)
    const float* ox = pk.org_x;
    const float* oy = pk.org_y;
    const float* oz = pk.org_z;
    const float* tmin = pk.tmin;
    alignas(64) float ix[NZ], iy[NZ], iz[NZ];   // 1 / dir, correctly rounded (box::robust::prepared's inv)
    alignas(64) float tmax[NZ];                 // the closest hit so far; -inf outside the group
    alignas(64) float sx[NZ], sy[NZ];           // watertight: shear (prepared's sx, sy)
    alignas(64) double rcpd[NZ], sxd[NZ], syd[NZ];   // watertight: prepared's rcp_dz, sx_d, sy_d
    std::uint32_t* const best = res.prim;       // each lane's best triangle so far (any hit: its hit)
    union PtStore {
        PtStore() noexcept {}
        TriPrepared value;
    } pt[NZ];                                   // the triangle test's setup, made at a lane's first candidate
    std::uint32_t have_pt = 0;
    bool sheared = false;      // watertight: sx, sy, rcpd, sxd, syd made for the group (make_shear)
    std::uint32_t alive = 0;   // lanes not finished (any hit: not yet occluded)
    int kx = 0, ky = 1, kz = 2;
    const float* okx = pk.org_x;   // watertight: origins along kx, ky, kz
    const float* oky = pk.org_y;
    const float* okz = pk.org_z;
    // lane masks from classify(): direction sign per axis, dominant axis
    std::uint32_t sign[3] = {0, 0, 0}, dominant[3] = {0, 0, 0};
    // Interval traversal (coherent groups): bounds of the group's origins, reciprocal directions, tmin.
    bool coherent = false;
    float oxlo = 0, oxhi = 0, oylo = 0, oyhi = 0, ozlo = 0, ozhi = 0;
    float ixlo = 0, ixhi = 0, iylo = 0, iyhi = 0, izlo = 0, izhi = 0, tminlo = 0;

    /// The traversal of packet `p` against (b, t); each traced lane's answer goes to `out`, whose lanes
    /// must hold misses (HitPacket's default) on entry: they are the lanes' state, so no group sets up
    /// or copies out hits.
    PacketTraversal(const WB& b, std::span<const Triangle<float>> t, const RayPacket<float, N>& p, const PacketConfig& cfg,
                    HitPacket<float, N>& out) noexcept
        : bvh(b), tris(t), pk(p), res(out), min_rays(cfg.min_rays), interval(cfg.interval) {}

    /// The lanes of `active` the packet takes: traceable rays without a direction component in
    /// (0, FLT_MIN) (those are the rays box::robust::prepared does not scale: t_scale 1). Computes the
    /// reciprocal directions (the same correctly rounded division as prepared) and the lane masks of
    /// direction signs (sign bit, so -0 counts as negative, as prepared's octant) and dominant axes
    /// (largest_axis of |dir|, as tri::watertight::prepared's kz).
    std::uint32_t classify(std::uint32_t active) noexcept {
        const R inf = V::set1(std::numeric_limits<float>::infinity()), zero = V::set1(0.0f), one = V::set1(1.0f);
        const R small = V::set1(std::numeric_limits<float>::min());
        std::uint32_t ok = 0;
        for (int h = 0; h < NS; ++h) {
            const int o = h * V::n;
            const R dxr = V::load(pk.dir_x + o), dyr = V::load(pk.dir_y + o), dzr = V::load(pk.dir_z + o);
            const R ax = V::abs(dxr), ay = V::abs(dyr), az = V::abs(dzr);
            const auto fin = V::band(V::band(V::band(V::lt(ax, inf), V::lt(ay, inf)), V::band(V::lt(az, inf), V::lt(V::abs(V::load(ox + o)), inf))),
                                  V::band(V::lt(V::abs(V::load(oy + o)), inf), V::lt(V::abs(V::load(oz + o)), inf)));
            const auto nonzero = V::bor(V::bor(V::ne(dxr, zero), V::ne(dyr, zero)), V::ne(dzr, zero));
            const auto tiny = V::bor(V::bor(V::band(V::gt(ax, zero), V::lt(ax, small)), V::band(V::gt(ay, zero), V::lt(ay, small))),
                                  V::band(V::gt(az, zero), V::lt(az, small)));
            const auto span = V::le(V::load(pk.tmin + o), V::load(pk.tmax + o));   // false for NaN
            ok |= (V::bits(V::band(V::band(fin, nonzero), span)) & ~V::bits(tiny)) << o;
            V::store(ix + o, V::div(one, dxr));
            V::store(iy + o, V::div(one, dyr));
            V::store(iz + o, V::div(one, dzr));
            sign[0] |= V::bits(dxr) << o;
            sign[1] |= V::bits(dyr) << o;
            sign[2] |= V::bits(dzr) << o;
            const std::uint32_t xy = V::bits(V::ge(ax, ay)) << o, xz = V::bits(V::ge(ax, az)) << o, yz = V::bits(V::ge(ay, az)) << o;
            dominant[0] |= xy & xz;
            dominant[1] |= ~xy & yz;
        }
        dominant[0] &= all_lanes<N>;
        dominant[1] &= all_lanes<N>;
        dominant[2] = all_lanes<N> & ~(dominant[0] | dominant[1]);
        return ok & active;
    }

    /// The lanes of `rest` with lane f's octant and dominant axis.
    std::uint32_t same_kind(std::uint32_t rest, int f) const noexcept {
        std::uint32_t g = rest;
        for (int a = 0; a < 3; ++a) g &= (sign[a] >> f & 1u) ? sign[a] : ~sign[a];
        if constexpr (std::is_same_v<Tri, tri::watertight>)
            for (int a = 0; a < 3; ++a)
                if (dominant[a] >> f & 1u) g &= dominant[a];
        return g;
    }

    /// Prepares the group's lanes (tmax, best, hit; for tri::watertight the axes, the shear at the first
    /// leaf: make_shear) and the interval bounds (`coherent` when no reciprocal direction component of the group is infinite). Lanes
    /// outside the group get tmax -inf: they never hit and do not widen the group's tmax bound.
    void begin_group(std::uint32_t group) noexcept {
        constexpr float inf = std::numeric_limits<float>::infinity();
        const int f = std::countr_zero(group);
        if constexpr (std::is_same_v<Tri, tri::watertight>) {
            kz = dominant[0] >> f & 1u ? 0 : dominant[1] >> f & 1u ? 1 : 2;
            kx = (kz + 1) % 3;
            ky = (kz + 2) % 3;
            const float* o[3] = {pk.org_x, pk.org_y, pk.org_z};
            okx = o[kx];
            oky = o[ky];
            okz = o[kz];
        }
        sheared = false;
        // the group's bounds: min / max over its lanes (the others masked to +-inf); named registers,
        // not arrays (GCC keeps arrays of registers on the stack)
        const R pinf = V::set1(inf), ninf = V::set1(-inf);
        R lox = pinf, loy = pinf, loz = pinf, lix = pinf, liy = pinf, liz = pinf, lot = pinf;
        R hox = ninf, hoy = ninf, hoz = ninf, hix = ninf, hiy = ninf, hiz = ninf;
        for (int h = 0; h < NS; ++h) {
            const int o = h * V::n;
            const auto g = V::from_bits(group >> o);   // all bits set in the group's lanes
            V::store(tmax + o, select(g, V::load(pk.tmax + o), ninf));
            const R X = V::load(ox + o), Y = V::load(oy + o), Z = V::load(oz + o);
            const R IX = V::load(ix + o), IY = V::load(iy + o), IZ = V::load(iz + o);
            lox = V::min(lox, select(g, X, pinf)); hox = V::max(hox, select(g, X, ninf));
            loy = V::min(loy, select(g, Y, pinf)); hoy = V::max(hoy, select(g, Y, ninf));
            loz = V::min(loz, select(g, Z, pinf)); hoz = V::max(hoz, select(g, Z, ninf));
            lix = V::min(lix, select(g, IX, pinf)); hix = V::max(hix, select(g, IX, ninf));
            liy = V::min(liy, select(g, IY, pinf)); hiy = V::max(hiy, select(g, IY, ninf));
            liz = V::min(liz, select(g, IZ, pinf)); hiz = V::max(hiz, select(g, IZ, ninf));
            lot = V::min(lot, select(g, V::load(tmin + o), pinf));
        }
        oxlo = hmin(lox); oxhi = hmax(hox);
        oylo = hmin(loy); oyhi = hmax(hoy);
        ozlo = hmin(loz); ozhi = hmax(hoz);
        ixlo = hmin(lix); ixhi = hmax(hix);
        iylo = hmin(liy); iyhi = hmax(hiy);
        izlo = hmin(liz); izhi = hmax(hiz);
        tminlo = hmin(lot);
        // interval traversal needs finite reciprocals (no direction component exactly 0)
        coherent = std::abs(ixlo) < inf && std::abs(ixhi) < inf && std::abs(iylo) < inf && std::abs(iyhi) < inf &&
                   std::abs(izlo) < inf && std::abs(izhi) < inf;
    }

    /// The group's watertight shear (tri::watertight::prepared's, the same operations): rcp = 1.0 /
    /// double(dir[kz]), sx = float(double(dir[kx]) * rcp), for every lane (only the group's are used).
    /// Made at the group's first leaf (test_triangles): most packets of a camera's background reach none.
    DYNBVH_NOINLINE void make_shear() noexcept {
        const float* d[3] = {pk.dir_x, pk.dir_y, pk.dir_z};
#if defined(DYNBVH_AVX)
        for (int o = 0; o < N; o += 4) {
            const __m256d rcp = _mm256_div_pd(_mm256_set1_pd(1.0), _mm256_cvtps_pd(_mm_load_ps(d[kz] + o)));
            const __m256d shx = _mm256_mul_pd(_mm256_cvtps_pd(_mm_load_ps(d[kx] + o)), rcp);
            const __m256d shy = _mm256_mul_pd(_mm256_cvtps_pd(_mm_load_ps(d[ky] + o)), rcp);
            _mm256_store_pd(rcpd + o, rcp);
            _mm256_store_pd(sxd + o, shx);
            _mm256_store_pd(syd + o, shy);
            _mm_store_ps(sx + o, _mm256_cvtpd_ps(shx));
            _mm_store_ps(sy + o, _mm256_cvtpd_ps(shy));
        }
#else
        for (int k = 0; k < N; ++k) {
            rcpd[k] = 1.0 / double(d[kz][k]);
            sxd[k] = double(d[kx][k]) * rcpd[k];
            syd[k] = double(d[ky][k]) * rcpd[k];
            sx[k] = float(sxd[k]);
            sy[k] = float(syd[k]);
        }
#endif
        sheared = true;
    }

    /// Lane k's triangle-test setup (made once per packet, at its first use).
    DYNBVH_ALWAYS_INLINE const TriPrepared& prepared_lane(int k) noexcept {
        if (!(have_pt >> k & 1u)) [[unlikely]] {
            // (watertight: from the group's set-up, begin_group, with the same operations)
            if constexpr (std::is_same_v<Tri, tri::watertight>)
                ::new (static_cast<void*>(&pt[k].value)) TriPrepared(pk.ray(k), kz, rcpd[k], sxd[k], syd[k]);
            else
                ::new (static_cast<void*>(&pt[k].value)) TriPrepared(pk.ray(k));
            have_pt |= std::uint32_t(1) << k;
        }
        return pt[k].value;
    }

    /// Slot s of node n against every ray (box::robust::test_octant lane by lane, the same operations as
    /// WideBoxTest): the lanes that hit, their entry distances in te, the nearest entry among them.
    template <int Oct>
    DYNBVH_ALWAYS_INLINE std::uint32_t slot_rays(const WN& n, int s, float* te, float& nearest) const noexcept {
        const R c = V::set1(2.0f * rounding_gamma<float>(3));   // box::robust::widen
        const R inf = V::set1(std::numeric_limits<float>::infinity());
        const R nx = V::set1(Oct & 1 ? n.hi_x[s] : n.lo_x[s]), fx = V::set1(Oct & 1 ? n.lo_x[s] : n.hi_x[s]);
        const R ny = V::set1(Oct & 2 ? n.hi_y[s] : n.lo_y[s]), fy = V::set1(Oct & 2 ? n.lo_y[s] : n.hi_y[s]);
        const R nz = V::set1(Oct & 4 ? n.hi_z[s] : n.lo_z[s]), fz = V::set1(Oct & 4 ? n.lo_z[s] : n.hi_z[s]);
        std::uint32_t bits = 0;
        R near = inf;
        for (int h = 0; h < NS; ++h) {
            const int o = h * V::n;
            const R X = V::load(ox + o), Y = V::load(oy + o), Z = V::load(oz + o);
            const R IX = V::load(ix + o), IY = V::load(iy + o), IZ = V::load(iz + o);
            const R x0 = V::mul(V::sub(nx, X), IX), x1 = V::mul(V::sub(fx, X), IX);
            const R y0 = V::mul(V::sub(ny, Y), IY), y1 = V::mul(V::sub(fy, Y), IY);
            const R z0 = V::mul(V::sub(nz, Z), IZ), z1 = V::mul(V::sub(fz, Z), IZ);
            const R tn = V::max(z0, V::max(y0, V::max(x0, V::load(tmin + o))));
            R tf = V::min(z1, V::min(y1, V::min(x1, V::load(tmax + o))));
            tf = V::add(tf, V::mul(c, V::abs(tf)));
            const auto hm = V::le(tn, tf);
            V::store(te + o, tn);
            near = V::min(near, select(hm, tn, inf));
            bits |= V::bits(hm) << o;
        }
        nearest = hmin(near);   // (may include a ray outside the caller's mask: only the visit order depends on it)
        return bits;
    }

    /// Child slots of node n hit by rays of `m`: per slot the ray mask, the entry distances (into
    /// te[slot]) and the nearest entry among those rays. Returns the number of hit slots (in slot[]).
    template <int Oct>
    DYNBVH_ALWAYS_INLINE int test_node(const WN& n, std::uint32_t m, int* slot, std::uint32_t* smask, float* snear,
                                       float (*te)[NZ]) const noexcept {
        int hits = 0;
        for (int s = 0; s < W; ++s) {
            if (n.empty_slot(s)) continue;
            const std::uint32_t bits = slot_rays<Oct>(n, s, te[hits], snear[hits]) & m;
            if (bits == 0) continue;
            slot[hits] = s;
            smask[hits] = bits;
            ++hits;
        }
        return hits;
    }

    /// The largest tmax of the group's unfinished rays (the others hold -inf).
    DYNBVH_ALWAYS_INLINE float tmax_bound() const noexcept {
        R m = V::load(tmax);
        for (int h = 1; h < NS; ++h) m = V::max(m, V::load(tmax + h * V::n));
        return hmax(m);
    }

    /// All W slots of node n against the whole group at once by interval arithmetic over the group's
    /// origins and reciprocal directions (every ray of a coherent group shares the octant Oct and has
    /// finite reciprocals): a slot any ray of the group hits under box::robust::test_octant passes,
    /// because each rounded operation is monotone, so the bounds computed from the interval ends bound
    /// every ray's own rounded entry from below and exit from above (tmax_hi: the largest tmax).
    /// tn[slot] gets the lower bound of the entry distances. The few slots that pass are then tested
    /// ray by ray only where it pays (leaves).
    template <int Oct>
    DYNBVH_ALWAYS_INLINE unsigned test_node_interval(const WN& n, float tmax_hi, float* tn) const noexcept {
        using B = lanes_for<W>;
        using BR = typename B::reg;
        const BR c = B::set1(2.0f * rounding_gamma<float>(3));
        // axis: near plane entry lower bound t0 and far plane exit upper bound t1 over the intervals
        auto axis = [](BR lo, BR hi, float olo, float ohi, float ilo, float ihi, bool neg, BR& t0, BR& t1) {
            const BR a = neg ? B::sub(hi, B::set1(olo)) : B::sub(lo, B::set1(ohi));   // near - o, at its smallest t
            const BR b = neg ? B::sub(lo, B::set1(ohi)) : B::sub(hi, B::set1(olo));   // far - o, at its largest t
            const BR il = B::set1(ilo), ih = B::set1(ihi);
            t0 = B::min(B::mul(a, il), B::mul(a, ih));
            t1 = B::max(B::mul(b, il), B::mul(b, ih));
        };
        unsigned mask = 0;
        for (int h = 0; h < W; h += B::n) {
            BR x0, x1, y0, y1, z0, z1;
            axis(B::load(n.lo_x + h), B::load(n.hi_x + h), oxlo, oxhi, ixlo, ixhi, (Oct & 1) != 0, x0, x1);
            axis(B::load(n.lo_y + h), B::load(n.hi_y + h), oylo, oyhi, iylo, iyhi, (Oct & 2) != 0, y0, y1);
            axis(B::load(n.lo_z + h), B::load(n.hi_z + h), ozlo, ozhi, izlo, izhi, (Oct & 4) != 0, z0, z1);
            const BR t_n = B::max(z0, B::max(y0, B::max(x0, B::set1(tminlo))));
            BR t_f = B::min(z1, B::min(y1, B::min(x1, B::set1(tmax_hi))));
            t_f = B::add(t_f, B::mul(c, B::abs(t_f)));
            B::store(tn + h, t_n);
            mask |= B::le_mask(t_n, t_f) << h;
        }
        return mask;
    }

    /// Lanes of `m` whose box entry `te` is not beyond their tmax (Box::before, lane by lane).
    DYNBVH_ALWAYS_INLINE std::uint32_t still_open(const float* te, std::uint32_t m) const noexcept {
        const R c = V::set1(2.0f * rounding_gamma<float>(3));
        std::uint32_t bits = 0;
        for (int h = 0; h < NS; ++h) {
            const int o = h * V::n;
            const R tm = V::load(tmax + o);
            bits |= V::bits(V::le(V::load(te + o), V::add(tm, V::mul(c, V::abs(tm))))) << o;
        }
        return bits & m;
    }

    /// Records a hit of lane k (already passed replaces_hit for closest hit).
    DYNBVH_ALWAYS_INLINE void take(int k, float t, float u, float v, std::uint32_t prim) noexcept {
        res.t[k] = t;
        res.u[k] = u;
        res.v[k] = v;
        best[k] = prim;
        if constexpr (AnyHit) {
            alive &= ~(std::uint32_t(1) << k);
            tmax[k] = -std::numeric_limits<float>::infinity();   // done: out of the group's tmax bound
        } else {
            tmax[k] = t;
        }
    }

    /// tri::watertight, step 1: the lanes of m the SIMD float filter keeps for the triangle `src` (no
    /// branch on the data, so the filters of a block's triangles overlap; see test_leaf_packet).
    template <class Src>
    DYNBVH_ALWAYS_INLINE std::uint32_t filter(const Src& src, std::uint32_t m) noexcept {
        using F = WatertightFilter<V>;
        const std::size_t X = std::size_t(kx), Y = std::size_t(ky), Z = std::size_t(kz);
        const R ax = V::set1(src.c(0, X)), ay = V::set1(src.c(0, Y)), az = V::set1(src.c(0, Z));
        const R bx = V::set1(src.c(1, X)), by = V::set1(src.c(1, Y)), bz = V::set1(src.c(1, Z));
        const R cx = V::set1(src.c(2, X)), cy = V::set1(src.c(2, Y)), cz = V::set1(src.c(2, Z));
        std::uint32_t rejected = 0;
        for (int h = 0; h < NS; ++h) {
            const int o = h * V::n;
            if (NS > 1 && (m >> o & step_lanes) == 0) continue;   // no ray of m in this step
            const R OX = V::load(okx + o), OY = V::load(oky + o), OZ = V::load(okz + o);
            const R SX = V::load(sx + o), SY = V::load(sy + o);
            const auto va = F::shear(V::sub(ax, OX), V::sub(ay, OY), V::sub(az, OZ), SX, SY);
            const auto vb = F::shear(V::sub(bx, OX), V::sub(by, OY), V::sub(bz, OZ), SX, SY);
            const auto vc = F::shear(V::sub(cx, OX), V::sub(cy, OY), V::sub(cz, OZ), SX, SY);
            rejected |= V::bits(F::rejects(va, vb, vc)) << o;
        }
        return m & ~rejected;
    }

    /// tri::watertight, step 2: the exact scalar test on each lane of `cand` (what filter kept), in
    /// lane order, and the hits that replace a lane's closest one.
    template <class Src>
    DYNBVH_ALWAYS_INLINE void confirm(const Src& src, std::uint32_t prim, std::uint32_t cand) noexcept {
        if (cand == 0) return;
#if defined(DYNBVH_AVX512)
        if constexpr (N % 16 == 0) {
            // every candidate of a 16-lane step, eight at a time, gathered into the lanes of one test
            const __m512i iota = _mm512_setr_epi32(0, 1, 2, 3, 4, 5, 6, 7, 8, 9, 10, 11, 12, 13, 14, 15);
            for (int o = 0; o < N; o += 16) {
                const std::uint32_t c16 = cand >> o & 0xffffu;
                if (c16 == 0) continue;
                const int count = std::popcount(c16);
                alignas(64) int lane[16];
                const __m512i idx = _mm512_maskz_compress_epi32(__mmask16(c16), iota);
                _mm512_store_si512(lane, idx);
                for (int b = 0; b < count; b += 8) {
                    alignas(32) float t8[8], u8[8], v8[8];
                    const __m512i at = b == 0 ? idx : _mm512_maskz_alignr_epi32(__mmask16(0xffff), idx, idx, 8);
                    const unsigned in = count - b >= 8 ? 0xffu : (1u << (count - b)) - 1u;
                    for (unsigned c = exact8(src, o, at, t8, u8, v8) & in; c != 0; c &= c - 1) {
                        const int j = std::countr_zero(c), k = o + lane[b + j];
                        if constexpr (!AnyHit)
                            if (!replaces_hit(t8[j], tmax[k], prim, best[k])) continue;
                        take(k, t8[j], u8[j], v8[j], prim);
                    }
                }
            }
            return;
        }
#endif
#if defined(DYNBVH_AVX)
        // four lanes at a time where at least three of them are candidates (a large triangle under a
        // packet), the others one by one
        if (std::popcount(cand) >= 3) {
            std::uint32_t lone = 0;
            for (std::uint32_t rest = cand; rest != 0;) {
                const int o = std::countr_zero(rest) & ~3;
                const std::uint32_t q = rest >> o & 0xfu;
                rest &= ~(std::uint32_t(0xf) << o);
                if (std::popcount(q) < 3) {
                    lone |= q << o;
                    continue;
                }
                alignas(16) float t4[4], u4[4], v4[4];
                for (std::uint32_t c = exact4(src, o, t4, u4, v4) & q; c != 0; c &= c - 1) {
                    const int j = std::countr_zero(c), k = o + j;
                    if constexpr (!AnyHit)
                        if (!replaces_hit(t4[j], tmax[k], prim, best[k])) continue;
                    take(k, t4[j], u4[j], v4[j], prim);
                }
            }
            cand = lone;
            if (cand == 0) return;
        }
#endif
        const Triangle<float> tr = src.get();
        for (std::uint32_t c = cand; c != 0; c &= c - 1) {
            const int k = std::countr_zero(c);
            float t, u, v;
            if (!tri::watertight::test(prepared_lane(k), tr, tmax[k], t, u, v)) continue;
            if constexpr (!AnyHit)
                if (!replaces_hit(t, tmax[k], prim, best[k])) continue;
            take(k, t, u, v, prim);
        }
    }

#if defined(DYNBVH_AVX)
    /// tri::watertight::test of the triangle `src` on lanes o .. o+3 at once (SSE float, AVX double):
    /// the scalar test's operations in the same order (the fused ones fused alike, detail::sub_mul
    /// etc.), so each lane's hit or miss and t, u, v are the scalar test's bits. Bit j of the result:
    /// lane o + j hits within [tmin, tmax]; its t, u, v are in t4[j], u4[j], v4[j].
    template <class Src>
    DYNBVH_ALWAYS_INLINE std::uint32_t exact4(const Src& src, int o, float* t4, float* u4, float* v4) const noexcept {
        const std::size_t X = std::size_t(kx), Y = std::size_t(ky), Z = std::size_t(kz);
        __m128 px[3], py[3], pz[3];
        for (int i = 0; i < 3; ++i) {
            px[i] = _mm_set1_ps(src.c(i, X));
            py[i] = _mm_set1_ps(src.c(i, Y));
            pz[i] = _mm_set1_ps(src.c(i, Z));
        }
        return exact_lanes<ExactLanes4>(px, py, pz, _mm_loadu_ps(okx + o), _mm_loadu_ps(oky + o), _mm_loadu_ps(okz + o), _mm_loadu_ps(sx + o),
                                        _mm_loadu_ps(sy + o), _mm256_load_pd(sxd + o), _mm256_load_pd(syd + o), _mm256_load_pd(rcpd + o),
                                        _mm_loadu_ps(tmin + o), _mm_loadu_ps(tmax + o), t4, u4, v4);
    }
#endif

#if defined(DYNBVH_AVX512)
    /// exact4's test on eight lanes of the 16-lane step at o, gathered: lane j of the test is ray
    /// o + at[j] (at: lane indices 0..15 in its lower eight 32-bit lanes). The same operations as the
    /// scalar test per lane (the same bits); bit j of the result: a hit within [tmin, tmax], with t, u,
    /// v in t8[j], u8[j], v8[j].
    template <class Src>
    DYNBVH_ALWAYS_INLINE unsigned exact8(const Src& src, int o, __m512i at, float* t8, float* u8, float* v8) const noexcept {
        const std::size_t X = std::size_t(kx), Y = std::size_t(ky), Z = std::size_t(kz);
        __m256 px[3], py[3], pz[3];
        for (int i = 0; i < 3; ++i) {
            px[i] = _mm256_set1_ps(src.c(i, X));
            py[i] = _mm256_set1_ps(src.c(i, Y));
            pz[i] = _mm256_set1_ps(src.c(i, Z));
        }
        return exact8_lanes(px, py, pz, o, at, t8, u8, v8);
    }

    /// exact8 with a triangle per lane: vertex i of lane j's triangle is (px[i], py[i], pz[i]) lane j,
    /// along kx, ky, kz.
    DYNBVH_ALWAYS_INLINE unsigned exact8_lanes(const __m256 (&px)[3], const __m256 (&py)[3], const __m256 (&pz)[3], int o, __m512i at,
                                               float* t8, float* u8, float* v8) const noexcept {
        const auto g32 = [&](const float* p) { return half8<0>(_mm512_maskz_permutexvar_ps(__mmask16(0xffff), at, _mm512_loadu_ps(p + o))); };
        const __m512i at64 = _mm512_maskz_cvtepu32_epi64(__mmask8(0xff), _mm256_castps_si256(half8<0>(_mm512_castsi512_ps(at))));
        const auto g64 = [&](const double* p) { return _mm512_permutex2var_pd(_mm512_loadu_pd(p + o), at64, _mm512_loadu_pd(p + o + 8)); };
        return exact_lanes<ExactLanes8>(px, py, pz, g32(okx), g32(oky), g32(okz), g32(sx), g32(sy), g64(sxd), g64(syd), g64(rcpd), g32(tmin),
                                        g32(tmax), t8, u8, v8);
    }
#endif

#if defined(DYNBVH_AVX512)
    /// tri::watertight on a block of eight against the rays of m (closest hit, packets of 16 and 32,
    /// AVX-512), in place of filter + confirm per triangle. Filter, per 16-lane step, the same float
    /// filter per (ray, triangle) pair as filter's: with more rays than triangles, triangle by triangle
    /// against the step's rays; else two rays at a time, each against the block's triangles (lanes 0-7
    /// the first ray, 8-15 the second), so a leaf that few rays reach costs few steps. Confirm: the
    /// pairs kept, in the filter's order, eight per exact8_lanes (rays gathered by lane
    /// index, triangles' vertices permuted per lane). A lane's triangles come in the block's order;
    /// a lane twice in one batch is tested against its tmax of the batch's start, so each hit is
    /// checked against the lane's current tmax again before replaces_hit: the hits of confirm's order.
    DYNBVH_ALWAYS_INLINE void test_block(const TriangleBlock<8>& b, int n, std::uint32_t m) noexcept {
        using F = WatertightFilter<V>;
        constexpr __mmask16 all = 0xffff;
        const __m512i iota = _mm512_setr_epi32(0, 1, 2, 3, 4, 5, 6, 7, 8, 9, 10, 11, 12, 13, 14, 15);
        const __m512i tri16 = _mm512_setr_epi32(0, 1, 2, 3, 4, 5, 6, 7, 0, 1, 2, 3, 4, 5, 6, 7);
        const unsigned used = (1u << n) - 1u;
        const __mmask16 valid = __mmask16(used | used << 8);   // (padding lanes have NaN vertices: never rejected)
        const std::size_t X = std::size_t(kx), Y = std::size_t(ky), Z = std::size_t(kz);
        // the block's vertices along kx, ky, kz, in both halves
        const auto dup = [&b](int i, std::size_t a) {
            const __m512 x = _mm512_maskz_loadu_ps(__mmask16(0x00ff), b.v[i][a]);
            return _mm512_maskz_shuffle_f32x4(all, x, x, 0x44);
        };
        const __m512 ax = dup(0, X), ay = dup(0, Y), az = dup(0, Z);
        const __m512 bx = dup(1, X), by = dup(1, Y), bz = dup(1, Z);
        const __m512 cx = dup(2, X), cy = dup(2, Y), cz = dup(2, Z);
        for (int o = 0; o < N; o += 16) {
            const std::uint32_t mr = m >> o & 0xffffu;
            if (mr == 0) continue;
            // Filter: the kept pairs as (lane, triangle), ray by ray.
            alignas(64) int rays[16], lane[16 * 8 + 16], tri[16 * 8 + 16];
            _mm512_store_si512(rays, _mm512_maskz_compress_epi32(__mmask16(mr), iota));
            const int nr = std::popcount(mr);
            const __m512 OX = _mm512_loadu_ps(okx + o), OY = _mm512_loadu_ps(oky + o), OZ = _mm512_loadu_ps(okz + o);
            const __m512 SX = _mm512_loadu_ps(sx + o), SY = _mm512_loadu_ps(sy + o);
            int count = 0;
            if (nr > n) {   // many rays: triangle by triangle against all of them (filter's steps)
                for (int j = 0; j < n; ++j) {
                    const auto bc = [&b, j](int i, std::size_t a) { return _mm512_set1_ps(b.v[i][a][j]); };
                    const auto va = F::shear(V::sub(bc(0, X), OX), V::sub(bc(0, Y), OY), V::sub(bc(0, Z), OZ), SX, SY);
                    const auto vb = F::shear(V::sub(bc(1, X), OX), V::sub(bc(1, Y), OY), V::sub(bc(1, Z), OZ), SX, SY);
                    const auto vc = F::shear(V::sub(bc(2, X), OX), V::sub(bc(2, Y), OY), V::sub(bc(2, Z), OZ), SX, SY);
                    const __mmask16 keep = __mmask16(~F::rejects(va, vb, vc) & mr);
                    _mm512_storeu_si512(lane + count, _mm512_maskz_compress_epi32(keep, iota));
                    _mm512_storeu_si512(tri + count, _mm512_set1_epi32(j));
                    count += std::popcount(unsigned(keep));
                }
            }
            for (int r = 0; r < nr && nr <= n; r += 2) {   // few rays: two at a time against all triangles
                const bool two = r + 1 < nr;
                const __m512i sel = _mm512_mask_blend_epi32(__mmask16(0xff00), _mm512_set1_epi32(rays[r]), _mm512_set1_epi32(two ? rays[r + 1] : rays[r]));
                const auto at = [&](__m512 x) { return _mm512_maskz_permutexvar_ps(all, sel, x); };
                const __m512 rox = at(OX), roy = at(OY), roz = at(OZ), shx = at(SX), shy = at(SY);
                const auto va = F::shear(V::sub(ax, rox), V::sub(ay, roy), V::sub(az, roz), shx, shy);
                const auto vb = F::shear(V::sub(bx, rox), V::sub(by, roy), V::sub(bz, roz), shx, shy);
                const auto vc = F::shear(V::sub(cx, rox), V::sub(cy, roy), V::sub(cz, roz), shx, shy);
                const __mmask16 keep = __mmask16(~F::rejects(va, vb, vc) & valid & (two ? 0xffffu : 0x00ffu));
                _mm512_storeu_si512(lane + count, _mm512_maskz_compress_epi32(keep, sel));
                _mm512_storeu_si512(tri + count, _mm512_maskz_compress_epi32(keep, tri16));
                count += std::popcount(unsigned(keep));
            }
            // Confirm, eight pairs at a time.
            for (int b0 = 0; b0 < count; b0 += 8) {
                const __m256i tj = _mm256_loadu_si256(reinterpret_cast<const __m256i*>(tri + b0));
                const auto vert = [&](int i, std::size_t a) { return _mm256_permutevar8x32_ps(_mm256_load_ps(b.v[i][a]), tj); };
                const __m256 px[3] = {vert(0, X), vert(1, X), vert(2, X)};
                const __m256 py[3] = {vert(0, Y), vert(1, Y), vert(2, Y)};
                const __m256 pz[3] = {vert(0, Z), vert(1, Z), vert(2, Z)};
                const __m512i at = _mm512_maskz_loadu_epi32(__mmask16(0x00ff), lane + b0);
                alignas(32) float t8[8], u8[8], v8[8];
                const unsigned in = count - b0 >= 8 ? 0xffu : (1u << (count - b0)) - 1u;
                for (unsigned c = exact8_lanes(px, py, pz, o, at, t8, u8, v8) & in; c != 0; c &= c - 1) {
                    const int j = std::countr_zero(c), k = o + lane[b0 + j];
                    const std::uint32_t prim = b.prim[tri[b0 + j]];
                    if (!(t8[j] <= tmax[k]) || !replaces_hit(t8[j], tmax[k], prim, best[k])) continue;
                    take(k, t8[j], u8[j], v8[j], prim);
                }
            }
        }
    }
#endif

    /// A triangle (user index prim) against the rays of m, for the policies other than tri::watertight
    /// (test_triangles). `src.c(vertex, axis)` reads a coordinate,
    /// `src.get()` the whole triangle (block lanes are read in place; the triangle is rebuilt only for
    /// the scalar confirmations).
    template <class Src>
    DYNBVH_ALWAYS_INLINE void test_triangle(const Src& src, std::uint32_t prim, std::uint32_t m) noexcept {
        if constexpr (std::is_same_v<Tri, tri::moller_trumbore>) {
            // the scalar test's operations lane by lane (vec.hpp's cross and dot, one division)
            const float p0x_ = src.c(0, 0), p0y_ = src.c(0, 1), p0z_ = src.c(0, 2);
            const float e1x_ = src.c(1, 0) - p0x_, e1y_ = src.c(1, 1) - p0y_, e1z_ = src.c(1, 2) - p0z_;
            const float e2x_ = src.c(2, 0) - p0x_, e2y_ = src.c(2, 1) - p0y_, e2z_ = src.c(2, 2) - p0z_;
            const R e1x = V::set1(e1x_), e1y = V::set1(e1y_), e1z = V::set1(e1z_);
            const R e2x = V::set1(e2x_), e2y = V::set1(e2y_), e2z = V::set1(e2z_);
            const R p0x = V::set1(p0x_), p0y = V::set1(p0y_), p0z = V::set1(p0z_);
            const R zero = V::set1(0.0f), one = V::set1(1.0f);
            alignas(64) float tt[NZ], uu[NZ], vv[NZ];
            std::uint32_t ok = 0;
            for (int h = 0; h < NS; ++h) {
                const int o = h * V::n;
                if (NS > 1 && (m >> o & step_lanes) == 0) continue;   // no ray of m in this step
                const R DX = V::load(pk.dir_x + o), DY = V::load(pk.dir_y + o), DZ = V::load(pk.dir_z + o);
                const R pvx = V::sub(V::mul(DY, e2z), V::mul(DZ, e2y));
                const R pvy = V::sub(V::mul(DZ, e2x), V::mul(DX, e2z));
                const R pvz = V::sub(V::mul(DX, e2y), V::mul(DY, e2x));
                const R det = V::add(V::add(V::mul(e1x, pvx), V::mul(e1y, pvy)), V::mul(e1z, pvz));
                const R inv = V::div(one, det);
                const R tvx = V::sub(V::load(ox + o), p0x), tvy = V::sub(V::load(oy + o), p0y), tvz = V::sub(V::load(oz + o), p0z);
                const R u = V::mul(V::add(V::add(V::mul(tvx, pvx), V::mul(tvy, pvy)), V::mul(tvz, pvz)), inv);
                const R qx = V::sub(V::mul(tvy, e1z), V::mul(tvz, e1y));
                const R qy = V::sub(V::mul(tvz, e1x), V::mul(tvx, e1z));
                const R qz = V::sub(V::mul(tvx, e1y), V::mul(tvy, e1x));
                const R v = V::mul(V::add(V::add(V::mul(DX, qx), V::mul(DY, qy)), V::mul(DZ, qz)), inv);
                const R t = V::mul(V::add(V::add(V::mul(e2x, qx), V::mul(e2y, qy)), V::mul(e2z, qz)), inv);
                const auto okr = V::band(V::band(V::band(V::ne(det, zero), V::ge(u, zero)), V::band(V::le(u, one), V::ge(v, zero))),
                                      V::band(V::le(V::add(u, v), one),
                                              V::band(V::ge(t, V::load(tmin + o)), V::le(t, V::load(tmax + o)))));
                V::store(tt + o, t);
                V::store(uu + o, u);
                V::store(vv + o, v);
                ok |= V::bits(okr) << o;
            }
            for (std::uint32_t c = ok & m; c != 0; c &= c - 1) {
                const int k = std::countr_zero(c);
                const float t = tt[k] + 0.0f;   // -0 -> +0, as the scalar test
                if constexpr (!AnyHit)
                    if (!replaces_hit(t, tmax[k], prim, best[k])) continue;
                take(k, t, uu[k], vv[k], prim);
            }
        } else {
            const Triangle<float> tr = src.get();
            for (std::uint32_t c = m; c != 0; c &= c - 1) {
                const int k = std::countr_zero(c);
                float t, u, v;
                if (!Tri::test(prepared_lane(k), tr, tmax[k], t, u, v)) continue;
                if constexpr (!AnyHit)
                    if (!replaces_hit(t, tmax[k], prim, best[k])) continue;
                take(k, t, u, v, prim);
            }
        }
    }

    /// Up to eight triangles of a leaf, src(j) and user index prim(j) for j < n, against the rays of m in
    /// the leaf's order. tri::watertight: every filter first (independent, so they overlap), then the
    /// exact tests (the filter does not read tmax: the same answers). False when an any-hit query has
    /// no ray left.
    template <class SrcAt, class PrimAt>
    DYNBVH_ALWAYS_INLINE bool test_triangles(int n, const SrcAt& src, const PrimAt& prim, std::uint32_t& m) noexcept {
        if constexpr (std::is_same_v<Tri, tri::watertight>) {
            if constexpr (AnyHit)
                if ((m &= alive) == 0) return false;
            if (!sheared) [[unlikely]] make_shear();
#if defined(DYNBVH_AVX512)
            if constexpr (!AnyHit && N % 16 == 0 && std::is_same_v<decltype(src(0)), BlockLane<8>>) {
                test_block(src(0).b, n, m);
                return true;
            }
#endif
            std::uint32_t cand[8];
            for (int j = 0; j < n; ++j) cand[j] = filter(src(j), m);
            for (int j = 0; j < n; ++j) {
                if constexpr (AnyHit) cand[j] &= alive;
                confirm(src(j), prim(j), cand[j]);
            }
        } else {
            for (int j = 0; j < n; ++j) {
                if constexpr (AnyHit)
                    if ((m &= alive) == 0) return false;
                test_triangle(src(j), prim(j), m);
            }
        }
        return true;
    }

    /// Leaf slot (first, count) against the rays of m: block by block, or eight index-leaf triangles at
    /// a time (test_triangles).
    DYNBVH_ALWAYS_INLINE void test_leaf_packet(I first, I count, std::uint32_t m) noexcept {
        if constexpr (WB::block_lanes > 0) {
            constexpr int BL = WB::block_lanes;
            const auto* blocks = bvh.blocks.data();
            const std::size_t end = std::size_t(first) + blocks_for<BL>(count);
            for (std::size_t i = first; i < end; ++i) {
                const auto& b = blocks[i];
                if (!test_triangles(int(b.count), [&b](int j) { return BlockLane<BL>{b, j}; },
                                    [&b](int j) { return b.prim[j]; }, m))
                    return;
            }
        } else {
            const I* ids = bvh.prim_ids.data();
            const Triangle<float>* lt = WB::precomputed ? bvh.leaf_triangles.data() : tris.data();
            const std::size_t end = std::size_t(first) + count;
#if defined(DYNBVH_AVX512)
            if constexpr (std::is_same_v<Tri, tri::watertight> && !AnyHit && N % 16 == 0) {
                // eight triangles at a time copied into a block on the stack, for test_block (a copy of
                // 8 triangles per packet is cheaper than the per-triangle filter and confirmations)
                if (!sheared) [[unlikely]] make_shear();
                for (std::size_t s0 = first; s0 < end; s0 += 8) {
                    const int n = int(std::min<std::size_t>(8, end - s0));
                    TriangleBlock<8> tb;
                    for (int j = 0; j < n; ++j) {
                        const std::size_t at = s0 + std::size_t(j);
                        tb.set(j, WB::precomputed ? lt[at] : lt[ids[at]], static_cast<std::uint32_t>(ids[at]));
                    }
                    tb.pad(n);
                    test_block(tb, n, m);
                }
                return;
            }
#endif
            for (std::size_t s0 = first; s0 < end; s0 += 8) {
                const auto at = [&](int j) { return s0 + std::size_t(j); };
                if (!test_triangles(int(std::min<std::size_t>(8, end - s0)),
                                    [&](int j) { return WholeTriangle{WB::precomputed ? lt[at(j)] : lt[ids[at(j)]]}; },
                                    [&](int j) { return static_cast<std::uint32_t>(ids[at(j)]); }, m))
                    return;
            }
        }
    }

    /// Lane k finishes the subtree (node, count) with the single-ray traversal, from its state.
    template <int Oct>
    DYNBVH_NOINLINE void finish_lane(int k, I node, I count) {
        const Ray<float> r = pk.ray(k);
        const box::robust::prepared<float> pb(r);
        const WideBoxTest<box::robust, float, W> wb(pb);
        using SE = WideStackEntry<I, float>;
        constexpr std::size_t cap = std::size_t(W - 1) * std::size_t(max_depth);
        const Hit<float> h0{res.t[k], res.u[k], res.v[k], invalid_prim};   // (the traversal reads t, u, v; prim is its output)
        Hit<float> h = h0;
        bool done;
        if (bvh.depth < max_depth) {
            SE stack[cap];
            done = wide_traverse_octant<Policy, AnyHit, Oct>(bvh, tris, r, 1.0f, wb, h, stack, cap, node, count, tmax[k], best[k]);
        } else {
            done = false;
        }
        if (!done) {   // a tree deeper than its depth field says: a stack that cannot overflow
            std::vector<SE> heap(std::size_t(W - 1) * (bvh.nodes.size() + 1));
            h = h0;
            wide_traverse_octant<Policy, AnyHit, Oct>(bvh, tris, r, 1.0f, wb, h, heap.data(), heap.size(), node, count, tmax[k],
                                                       best[k]);
        }
        if constexpr (AnyHit) {
            if (h.prim != invalid_prim) take(k, h.t, h.u, h.v, h.prim);
        } else {
            res.set(k, h);   // (h.prim is the lane's best triangle, or invalid_prim)
            tmax[k] = h.prim != invalid_prim ? h.t : tmax[k];
        }
    }

    /// Traces the rays of `group` (all of octant Oct) from the root; false when the stack of `cap`
    /// entries would overflow (a tree whose depth field is wrong: the caller redoes the rays alone).
    /// `leaf(first, count, m)` tests leaf slot (first, count) against the rays of m and records their
    /// hits with take() (the triangle leaves: test_leaf_packet; two_level.hpp's top level: instances).
    /// Alone: rays fewer than min_rays in a subtree finish it alone (finish_lane); false keeps every
    /// ray in the packet down to the leaves.
    template <int Oct, bool Alone = true, class Leaf>
    bool run(std::uint32_t group, Entry* stack, std::size_t cap, const Leaf& leaf) {
        alive = group;
        std::size_t sp = 0;
        I cur = 0, cur_count = 0;
        std::uint32_t m = group;
        int slot[WZ];
        std::uint32_t smask[WZ];
        float snear[WZ];
        alignas(64) float te[WZ][NZ];
        for (;;) {
            if constexpr (AnyHit) m &= alive;   // occluded rays are done
            bool few = m == 0;
            if constexpr (Alone) few = unsigned(std::popcount(m)) < min_rays;
            if (few) {   // few rays left here: each goes on alone
                if constexpr (Alone)
                    for (std::uint32_t c = m; c != 0; c &= c - 1) finish_lane<Oct>(std::countr_zero(c), cur, cur_count);
            } else if (cur_count == 0) {
                const int nh = test_node<Oct>(bvh.nodes[cur], m, slot, smask, snear, te);
                if (nh != 0) {
                    // nearest first: sort the hit slots by their nearest entry, push all but the nearest
                    int order[WZ];
                    order_by_distance<W>(snear, nh, order);
                    if (sp + std::size_t(nh) > cap) [[unlikely]] return false;
                    const WN& n = bvh.nodes[cur];
                    for (int i = nh - 1; i > 0; --i) {
                        const int q = order[i];
                        Entry& e = stack[sp++];
                        std::copy(te[q], te[q] + N, e.tentry);
                        e.child = n.child[slot[q]];
                        e.count = n.count[slot[q]];
                        e.mask = smask[q];
                    }
                    const int q = order[0];
                    cur = n.child[slot[q]];
                    cur_count = n.count[slot[q]];
                    m = smask[q];
                    continue;
                }
            } else {
                leaf(cur, cur_count, m);
            }
            // Pop the next entry that still holds rays which may find a closer hit there.
            for (;;) {
                if constexpr (AnyHit)
                    if (alive == 0) return true;
                if (sp == 0) return true;
                const Entry& e = stack[--sp];
                std::uint32_t em = e.mask;
                if constexpr (AnyHit) em &= alive;
                if (em == 0) continue;
                em = still_open(e.tentry, em);
                if (em == 0) continue;
                cur = e.child;
                cur_count = e.count;
                m = em;
                break;
            }
        }
    }

    /// The interval traversal of a coherent group: inner nodes are tested for the whole group at once
    /// (test_node_interval) and entered by every unfinished ray; leaf slots are tested ray by ray, and
    /// only the rays that hit a leaf's box test its triangles. Conservative at every step, so each ray
    /// gets its single-ray answer (extra visits cannot change an order-independent answer). `leaf` as
    /// for run().
    template <int Oct, class Leaf>
    bool run_interval(std::uint32_t group, IntervalEntry<I>* stack, std::size_t cap, const Leaf& leaf) {
        using IE = IntervalEntry<I>;
        alive = group;
        std::size_t sp = 0;
        I cur = 0, cur_count = 0;
        std::uint32_t m = group;
        alignas(64) float tn[WZ];
        alignas(64) float te[NZ];
        int order[WZ];
        IE found[WZ];
        float thi = tmax_bound();   // the group's largest tmax, renewed after each leaf
        for (;;) {
            if constexpr (AnyHit) m &= alive;
            if (m == 0) {
            } else if (cur_count == 0) {
                const WN& n = bvh.nodes[cur];
                unsigned mask = test_node_interval<Oct>(n, thi, tn);
                int nh = 0;
                for (; mask != 0; mask &= mask - 1) {
                    const int s = std::countr_zero(mask);
                    std::uint32_t sm = alive;
                    float near = tn[s];
                    if (n.count[s] != 0) {   // a leaf: only the rays that hit its box
                        sm &= slot_rays<Oct>(n, s, te, near);
                        if (sm == 0) continue;
                    }
                    found[nh] = IE{n.child[s], n.count[s], sm, near};
                    ++nh;
                }
                if (nh != 0) {
                    float dist[WZ];
                    for (int i = 0; i < nh; ++i) dist[i] = found[i].tentry;
                    order_by_distance<W>(dist, nh, order);
                    if (sp + std::size_t(nh) > cap) [[unlikely]] return false;
                    for (int i = nh - 1; i > 0; --i) stack[sp++] = found[order[i]];
                    const IE& e = found[order[0]];
                    cur = e.child;
                    cur_count = e.count;
                    m = e.mask;
                    continue;
                }
            } else {
                leaf(cur, cur_count, m);
                thi = tmax_bound();
            }
            // Pop the next entry some of whose rays may still find a closer hit there.
            for (;;) {
                if constexpr (AnyHit)
                    if (alive == 0) return true;
                if (sp == 0) return true;
                const IE& e = stack[--sp];
                std::uint32_t em = e.mask;
                if constexpr (AnyHit) em &= alive;
                if (em == 0) continue;
                if (!box::robust::before(e.tentry, thi)) continue;
                cur = e.child;
                cur_count = e.count;
                m = em;
                break;
            }
        }
    }

    /// Each group of the lanes of `packable` (rays of one kind, see same_kind) with at least
    /// max(min_group, 2) rays: begin_group(g), then `f(g, octant)` (octant: a std::integral_constant of
    /// the group's direction octant) traces it and returns whether it did. Returns the lanes left to the
    /// single-ray query: the smaller groups and those f did not trace.
    template <class F>
    std::uint32_t for_each_group(std::uint32_t packable, unsigned min_group, const F& f) {
        std::uint32_t alone = 0;
        for (std::uint32_t rest = packable; rest != 0;) {
            const int first = std::countr_zero(rest);
            const std::uint32_t g = same_kind(rest, first);
            rest &= ~g;
            if (unsigned(std::popcount(g)) < std::max(min_group, 2u)) {
                alone |= g;
                continue;
            }
            begin_group(g);
            const int octant = int(sign[0] >> first & 1u) | int(sign[1] >> first & 1u) << 1 | int(sign[2] >> first & 1u) << 2;
            if (!dispatch_octant(octant, [&](auto o) { return f(g, o); })) alone |= g;
        }
        return alone;
    }

    /// Traces `group` (octant Oct), on the fixed stack or, for a tree deeper than it, on the heap.
    template <int Oct>
    void trace(std::uint32_t group) {
        bool ok;
        const bool fits = bvh.depth < fixed_levels;
        const std::size_t heap_cap = std::size_t(W - 1) * (bvh.nodes.size() + 1) + 1;
        const auto leaves = [this](I first, I count, std::uint32_t m) { test_leaf_packet(first, count, m); };
        if (coherent && interval) {
            if (fits) {
                IntervalEntry<I> stack[fixed_cap];
                ok = run_interval<Oct>(group, stack, fixed_cap, leaves);
            } else {
                std::vector<IntervalEntry<I>> heap(heap_cap);
                ok = run_interval<Oct>(group, heap.data(), heap.size(), leaves);
            }
        } else {
            if (fits) {
                Entry stack[fixed_cap];
                ok = run<Oct>(group, stack, fixed_cap, leaves);
            } else {
                std::vector<Entry> heap(heap_cap);
                ok = run<Oct>(group, heap.data(), heap.size(), leaves);
            }
        }
        if (!ok) [[unlikely]]   // the tree is deeper than its depth field: every ray of the group alone
            for (std::uint32_t c = group; c != 0; c &= c - 1) {
                const int k = std::countr_zero(c);
                res.set(k, single_lane<Policy, AnyHit>(bvh, tris, pk.ray(k)));
            }
    }
};

/// Groups the active lanes by octant (and dominant axis), traces each group large enough as a packet
/// and the other lanes ray by ray; out[k] gets lane k's answer.
template <class Tri, bool AnyHit, class WN, class P, int N>
void packet_traverse(const WideBvh<WN, P>& bvh, std::span<const Triangle<float>> tris, const RayPacket<float, N>& packet,
                     std::uint32_t active, const PacketConfig& cfg, HitPacket<float, N>& out) {
    using Policy = trace::policy<box::robust, Tri>;
    using PT = PacketTraversal<Tri, AnyHit, WN, P, N>;
    if (bvh.nodes.empty()) return;
    PT st(bvh, tris, packet, cfg, out);   // (the traced lanes' answers land in out)
    const std::uint32_t packable = st.classify(active);
    // every ray the packet does not take, and the few of a kind, go alone
    const std::uint32_t alone = (active & ~packable) | st.for_each_group(packable, cfg.min_rays, [&](std::uint32_t g, auto o) {
        st.template trace<decltype(o)::value>(g);
        return true;
    });
    for (std::uint32_t c = alone; c != 0; c &= c - 1) {
        const int k = std::countr_zero(c);
        out.set(k, single_lane<Policy, AnyHit>(bvh, tris, packet.ray(k)));
    }
}
#endif  // DYNBVH_SSE

/// Packet query: lane k of `out` (all misses on entry) gets the single-ray answer of every active lane.
template <class Policy, bool AnyHit, class WN, class P, int N, class S = typename WN::scalar_type>
void packet_query(const WideBvh<WN, P>& bvh, std::span<const Triangle<S>> tris, const RayPacket<S, N>& packet, std::uint32_t active,
                  const PacketConfig& cfg, HitPacket<S, N>& out) {
    active &= all_lanes<N>;
#if defined(DYNBVH_SSE)
    if constexpr (std::is_same_v<S, float> && std::is_same_v<typename Policy::box_test, box::robust>) {
        packet_traverse<typename Policy::triangle_test, AnyHit>(bvh, tris, packet, active, cfg, out);
        return;
    }
#endif
    (void)cfg;
    for (std::uint32_t c = active; c != 0; c &= c - 1) {
        const int k = std::countr_zero(c);
        out.set(k, single_lane<Policy, AnyHit>(bvh, tris, packet.ray(k)));
    }
}

} // namespace detail

/// Closest hits of the active lanes of `packet` (bit k of `active` set; bits from N on are ignored) in a
/// wide BVH: lane k of the result is, bit for bit, `intersect<Policy>(bvh, tris, packet.ray(k))`;
/// inactive lanes get the miss value Hit{}. `tris` as for the single-ray intersect (a wrong size throws
/// std::invalid_argument). Fastest for coherent rays (a tile of camera rays, shadow rays towards one
/// light); see the file comment for the traversal and `cfg`.
template <class Policy = trace::robust, class WN, class P, int N>
HitPacket<typename WN::scalar_type, N> intersect(const WideBvh<WN, P>& bvh,
                                                 std::type_identity_t<std::span<const Triangle<typename WN::scalar_type>>> tris,
                                                 const RayPacket<typename WN::scalar_type, N>& packet,
                                                 std::uint32_t active = all_lanes<N>, const PacketConfig& cfg = {}) {
    using S = typename WN::scalar_type;
    detail::check_triangles(bvh, tris.size(), "intersect", !WideBvh<WN, P>::precomputed);
    HitPacket<S, N> res;
    detail::packet_query<Policy, false>(bvh, tris, packet, active, cfg, res);
    return res;
}

/// Any-hit query of the active lanes of `packet` (shadow rays): bit k of the result is set when lane k
/// is active and `occluded<Policy>(bvh, tris, packet.ray(k))` is true. Stops each ray at its first hit.
template <class Policy = trace::robust, class WN, class P, int N>
std::uint32_t occluded(const WideBvh<WN, P>& bvh, std::type_identity_t<std::span<const Triangle<typename WN::scalar_type>>> tris,
                       const RayPacket<typename WN::scalar_type, N>& packet, std::uint32_t active = all_lanes<N>,
                       const PacketConfig& cfg = {}) {
    using S = typename WN::scalar_type;
    detail::check_triangles(bvh, tris.size(), "occluded", !WideBvh<WN, P>::precomputed);
    HitPacket<S, N> res;
    detail::packet_query<Policy, true>(bvh, tris, packet, active, cfg, res);
    return res.hit_mask();
}

} // namespace dynbvh
