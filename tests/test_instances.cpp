// two_level.hpp and affine.hpp: a two-level scene's closest hit equals brute force over every instance
// with the same ray transformation (object_ray, then the watertight test in object space), bit for bit;
// rigid updates reuse the object trees; deformed objects are refitted; empty scenes and bad input.
#include "support.hpp"
#include "hit_compare.hpp"

#include <cmath>
#include <limits>
#include <string>
#include <type_traits>
#include <vector>

#include <dynbvh/affine.hpp>
#include <dynbvh/mesh.hpp>
#include <dynbvh/packet.hpp>
#include <dynbvh/two_level.hpp>

using namespace dynbvh;
using namespace dynbvh::test;

namespace {

constexpr float nan_f = std::numeric_limits<float>::quiet_NaN();

/// A random rotation (unit quaternion), a random scale per axis in [0.3, 3] (negative on one axis when
/// `mirror`: determinant < 0) and a translation `centre` + [-spread, spread]^3.
Affinef random_transform(Rng& r, Vec3f centre, float spread, bool mirror) {
    float q[4];
    float len = 0;
    do {
        len = 0;
        for (float& x : q) { x = r.uniform(-1, 1); len += x * x; }
    } while (len < 1e-3f || len > 1);
    for (float& x : q) x /= std::sqrt(len);
    const float w = q[0], x = q[1], y = q[2], z = q[3];
    const float rot[3][3] = {{1 - 2 * (y * y + z * z), 2 * (x * y - w * z), 2 * (x * z + w * y)},
                             {2 * (x * y + w * z), 1 - 2 * (x * x + z * z), 2 * (y * z - w * x)},
                             {2 * (x * z - w * y), 2 * (y * z + w * x), 1 - 2 * (x * x + y * y)}};
    const float s[3] = {r.uniform(0.3f, 3.0f) * (mirror ? -1.0f : 1.0f), r.uniform(0.3f, 3.0f), r.uniform(0.3f, 3.0f)};
    Affinef a;
    for (int i = 0; i < 3; ++i)
        for (int j = 0; j < 3; ++j) a.m[std::size_t(4 * i + j)] = rot[i][j] * s[j];
    a.m[3] = centre.x + r.uniform(-spread, spread);
    a.m[7] = centre.y + r.uniform(-spread, spread);
    a.m[11] = centre.z + r.uniform(-spread, spread);
    return a;
}

/// Object `object`'s triangles as the scene reads them (given as a span or a view).
template <class Scene>
std::vector<Trianglef> object_tris(const Scene& scene, std::uint32_t object) {
    std::vector<Trianglef> t(scene.object_triangle_count(object));
    for (std::size_t i = 0; i < t.size(); ++i) t[i] = scene.object_triangle(object, i);
    return t;
}

/// The test's own reference: every instance in order, object_ray with the scene's inverse, every finite
/// triangle with the watertight test, tmax narrowing.
template <class Scene>
InstanceHit<float> reference(const Scene& scene, const Rayf& ray) {
    InstanceHit<float> best;
    if (!traceable(ray)) return best;
    float tmax = ray.tmax;
    for (std::size_t k = 0; k < scene.instance_count(); ++k) {
        const std::uint32_t object = scene.instances()[k].object;
        Rayf r = object_ray(scene.inverse_transform(k), Rayf{ray.org, ray.dir, ray.tmin, tmax});
        for (std::size_t i = 0; i < scene.object_triangle_count(object); ++i) {
            const Trianglef tri = scene.object_triangle(object, i);
            if (!tri.is_finite()) continue;
            r.tmax = tmax;
            const Hitf h = intersect_triangle<tri::watertight>(tri, r);
            if (h) {
                best.t = h.t;
                best.u = h.u;
                best.v = h.v;
                best.prim = std::uint32_t(i);
                best.instance = std::uint32_t(k);
                tmax = h.t;
            }
        }
    }
    return best;
}

/// Same closest hit: both miss, or the same t to the bit and the same (instance, triangle), or the
/// reported one is hit at exactly that t through the same arithmetic.
template <class Scene>
bool same_instance_hit(const Scene& scene, const InstanceHit<float>& h, const InstanceHit<float>& e, const Rayf& ray) {
    if (bool(h) != bool(e)) return false;
    if (!h) return true;
    if (!same_bits(h.t, e.t)) return false;
    if (h.instance == e.instance && h.prim == e.prim) return same_bits(h.u, e.u) && same_bits(h.v, e.v);
    if (h.instance >= scene.instance_count()) return false;
    const auto tris = object_tris(scene, scene.instances()[h.instance].object);
    if (h.prim >= tris.size()) return false;
    return same_bits(intersect_triangle<tri::watertight>(tris[h.prim], object_ray(scene.inverse_transform(h.instance), ray)).t, h.t);
}

/// Rays at random points of random instances' world boxes from far around, axis-parallel ones, misses,
/// clipped intervals, and untraceable ones.
template <class Scene>
std::vector<Rayf> scene_rays(const Scene& scene, std::size_t n, std::uint64_t seed) {
    Rng r(seed);
    std::vector<Rayf> rays;
    const AABBf world = scene.top().bounds();
    const float reach = 2 * length(world.diagonal()) + 10;
    for (std::size_t i = 0; i < n && !scene.top().empty(); ++i) {
        const std::uint32_t k = std::uint32_t(r.next() % scene.instance_count());
        const auto& inst = scene.instances()[k];
        const auto tris = object_tris(scene, inst.object);
        Vec3f target = inst.transform.point(Vec3f{});
        if (!tris.empty() && i % 8 >= 6) {
            // A vertex on the object's bounding box (the extreme one along a random axis): its hit lies on
            // the box's surface, where culling without the padding of two_level.hpp would lose it.
            const std::size_t axis = r.next() % 3;
            const bool hi = r.next() % 2 == 0;
            Vec3f best = tris[0].p0;
            for (const auto& t : tris)
                for (const Vec3f& p : {t.p0, t.p1, t.p2})
                    if (hi ? p[axis] > best[axis] : p[axis] < best[axis]) best = p;
            target = inst.transform.point(best);
        } else if (!tris.empty()) {   // a point on one of its triangles (hits likely), or near it
            const Trianglef& t = tris[r.next() % tris.size()];
            const float a = r.uniform(), b = r.uniform() * (1 - a);
            target = inst.transform.point(t.p0 + (t.p1 - t.p0) * a + (t.p2 - t.p0) * b);
        }
        Vec3f org = target + Vec3f{r.uniform(-1, 1), r.uniform(-1, 1), r.uniform(-1, 1)} * reach;
        Rayf ray{org, target - org};
        switch (i % 8) {
        case 1: ray.dir = {0, 0, target.z > org.z ? 1.0f : -1.0f}; ray.org = {target.x, target.y, org.z}; break;   // axis-parallel
        case 2: ray.dir = Vec3f{r.uniform(-1, 1), r.uniform(-1, 1), r.uniform(-1, 1)}; break;                     // likely a miss
        case 3: ray.tmax = 0.5f; break;                                                                            // clipped
        case 4: ray.tmin = 0.5f; break;
        case 5: ray.org = target; ray.tmin = -1.0f; break;   // starts at the surface, interval both ways
        case 7: {   // from afar, at a point within the rounding of the object ray of the box's surface
            const float dist = 1e4f * reach;
            const Vec3f jitter = Vec3f{r.uniform(-1, 1), r.uniform(-1, 1), r.uniform(-1, 1)} * (4e-7f * dist);
            ray.org = target - normalize(ray.dir) * dist;
            ray.dir = target + jitter - ray.org;
            break;
        }
        default: break;
        }
        rays.push_back(ray);
    }
    rays.push_back({{nan_f, 0, 0}, {0, 0, 1}});
    rays.push_back({{0, 0, 0}, {0, 0, 0}});
    rays.push_back({{0, 0, 0}, {1, nan_f, 0}});
    return rays;
}

/// Bit for bit the same hit, instance included.
bool identical(const InstanceHit<float>& a, const InstanceHit<float>& b) {
    return same_bits(a.t, b.t) && same_bits(a.u, b.u) && same_bits(a.v, b.v) && a.prim == b.prim && a.instance == b.instance;
}

/// Packets of N of `rays` (in order, so coherent runs stay together) under several lane masks and packet
/// knobs: every active lane gets the single-ray intersect / occluded answer bit for bit, every inactive
/// lane the miss value.
template <int N, class Scene>
std::size_t packet_mismatches(const Scene& scene, const std::vector<Rayf>& rays, const std::string& what) {
    std::size_t bad = 0;
    const std::uint32_t masks[] = {all_lanes<N>, 0x5555u & all_lanes<N>, 0x0f0fu & all_lanes<N>, 1u, 0u};
    const PacketConfig cfgs[] = {{}, {.min_rays = 1, .interval = false}, {.min_rays = N + 1}};
    for (std::size_t first = 0; first < rays.size(); first += N) {
        RayPacket<float, N> p;
        for (int k = 0; k < N; ++k) p.set(k, rays[(first + std::size_t(k)) % rays.size()]);
        for (const std::uint32_t m : masks)
            for (const PacketConfig& cfg : cfgs) {
                const InstanceHitPacket<float, N> h = scene.intersect(p, m, cfg);
                const std::uint32_t occ = scene.occluded(p, m, cfg);
                for (int k = 0; k < N; ++k) {
                    const bool on = (m >> k & 1u) != 0;
                    const InstanceHit<float> e = on ? scene.intersect(p.ray(k)) : InstanceHit<float>{};
                    const bool eo = on && scene.occluded(p.ray(k));
                    if (identical(h.hit(k), e) && bool(occ >> k & 1u) == eo) continue;
                    if (++bad <= 3)
                        MESSAGE(what, " packet of ", N, " lane ", k, " mask ", m, ": ray ", describe(p.ray(k)), ": instance ",
                                h.instance[k], " prim ", h.prim[k], " t ", h.t[k], " / single ray ", e.instance, " prim ", e.prim,
                                " t ", e.t, "; occluded ", (occ >> k & 1u), " / ", eo);
                }
            }
    }
    return bad;
}

/// Coherent packets: 4x4 tiles of rays from a point towards the neighbourhood of an instance (as a
/// camera's tiles), some with clipped intervals.
template <class Scene>
std::vector<Rayf> tile_rays(const Scene& scene, std::size_t tiles, std::uint64_t seed) {
    Rng r(seed);
    std::vector<Rayf> rays;
    if (scene.top().empty()) return rays;
    const float reach = length(scene.top().bounds().diagonal()) + 10;
    for (std::size_t i = 0; i < tiles; ++i) {
        const auto& inst = scene.instances()[r.next() % scene.instance_count()];
        const Vec3f target = inst.transform.point(Vec3f{});
        const Vec3f org = target + Vec3f{r.uniform(-1, 1), r.uniform(-1, 1), r.uniform(-1, 1)} * reach;
        const float spread = r.uniform(0.001f, 0.05f) * reach;
        for (int y = 0; y < 4; ++y)
            for (int x = 0; x < 4; ++x) {
                Rayf ray{org, target + Vec3f{float(x) - 1.5f, float(y) - 1.5f, 0.5f * float(x - y)} * spread - org};
                if (i % 4 == 3) ray.tmax = 0.9f;
                rays.push_back(ray);
            }
    }
    return rays;
}

template <class Scene>
void check_packets(const Scene& scene, const std::vector<Rayf>& rays, const std::string& what) {
    std::vector<Rayf> all = tile_rays(scene, sanitizer_scaled(std::size_t(12)), 3);
    all.insert(all.end(), rays.begin(), rays.end());
    const std::size_t bad = packet_mismatches<16>(scene, all, what) + packet_mismatches<8>(scene, all, what) +
                              packet_mismatches<32>(scene, all, what);
    CHECK_MESSAGE(bad == 0, what, ": ", bad, " packet lanes differ from the single-ray query");
}

template <class Scene>
void check_scene(const Scene& scene, std::uint64_t seed, const std::string& what, std::size_t n = 300) {
    std::size_t bad = 0, hits = 0, checked = 0;
    for (const Rayf& ray : scene_rays(scene, sanitizer_scaled(n), seed)) {
        const InstanceHit<float> h = scene.intersect(ray);
        const InstanceHit<float> e = reference(scene, ray);
        const InstanceHit<float> b = scene.brute_force_intersect(ray);
        ++checked;
        hits += bool(e);
        bool ok = same_instance_hit(scene, h, e, ray) && same_instance_hit(scene, b, e, ray);
        ok = ok && scene.occluded(ray) == bool(e) && scene.brute_force_occluded(ray) == bool(e);
        if (!ok && ++bad <= 3)
            MESSAGE(what, ": ray ", describe(ray), ": got instance ", h.instance, " prim ", h.prim, " t ", h.t,
                    " / expected instance ", e.instance, " prim ", e.prim, " t ", e.t);
    }
    CHECK_MESSAGE(bad == 0, what, ": ", bad, " of ", checked, " rays differ from brute force");
    CHECK_MESSAGE(hits * 4 > checked, what, ": only ", hits, " of ", checked, " rays hit");
    check_packets(scene, scene_rays(scene, sanitizer_scaled(n / 3), seed + 7), what);
}

std::vector<Trianglef> plane_mesh() {   // a 4x4 grid of quads in z = 0 (shared edges and vertices)
    std::vector<Trianglef> t;
    for (int i = 0; i < 4; ++i)
        for (int j = 0; j < 4; ++j) {
            const Vec3f a{float(i), float(j), 0}, b{float(i + 1), float(j), 0}, c{float(i + 1), float(j + 1), 0},
                d{float(i), float(j + 1), 0};
            t.push_back({a, b, c});
            t.push_back({a, c, d});
        }
    return t;
}

template <class Scene>
std::vector<Instance<float>> random_instances(const Scene& scene, std::size_t n, std::uint64_t seed, Vec3f centre, float spread) {
    Rng r(seed);
    std::vector<Instance<float>> out(n);
    for (std::size_t i = 0; i < n; ++i) {
        out[i].object = std::uint32_t(r.next() % scene.object_count());
        out[i].transform = random_transform(r, centre, spread, i % 3 == 0);
    }
    return out;
}

template <class Builder, class Prim, class Exec>
void random_scenes(const Exec& ex, const std::string& name) {
    const auto ball = sphere(8, 16);
    const auto soup = random_soup(150, 5, 0.2f);
    const auto plane = plane_mesh();
    const std::vector<Trianglef> empty;
    TwoLevel<Builder, Node<>, Prim, Exec> scene({}, ex);
    scene.add_object(ball);
    scene.add_object(soup);
    scene.add_object(plane);
    scene.add_object(empty);
    struct Case { Vec3f centre; float spread; std::size_t n; };
    const Case cases[] = {{{0, 0, 0}, 10, 30}, {{1e4f, -2e4f, 3e4f}, 20, 25}, {{0, 0, 0}, 2, 12}, {{-5e5f, 0, 0}, 50, 8}};
    std::uint64_t seed = 1;
    for (const Case& c : cases) {
        scene.set_instances(random_instances(scene, c.n, seed, c.centre, c.spread));
        scene.commit();
        check_scene(scene, seed + 100, name + " centre " + std::to_string(c.centre.x));
        ++seed;
    }
}

} // namespace

TEST_CASE("affine: inverse undoes the transform; object_ray keeps t") {
    Rng r(9);
    for (int i = 0; i < 50; ++i) {
        const Affinef m = random_transform(r, {100, -50, 7}, 30, i % 2 == 0);
        const Affinef inv = inverse(m);
        const Vec3f p{r.uniform(-5, 5), r.uniform(-5, 5), r.uniform(-5, 5)};
        const Vec3f back = inv.point(m.point(p));
        CHECK(length(back - p) < 1e-3f);
        // The point at parameter t maps to the object ray's point at the same t.
        const Rayf w{{r.uniform(-9, 9), r.uniform(-9, 9), r.uniform(-9, 9)}, {r.uniform(-1, 1), r.uniform(-1, 1), 1}};
        const Rayf o = object_ray(inv, w);
        const float t = 3.5f;
        CHECK(length(m.point(o.org + o.dir * t) - (w.org + w.dir * t)) < 1e-3f);
        CHECK(o.tmin == w.tmin);
        CHECK(o.tmax == w.tmax);
    }
    Affinef singular;
    singular.m[5] = 0;   // y row zero
    CHECK_THROWS_WITH_AS(inverse(singular, "instances[3].transform"), doctest::Contains("instances[3].transform is singular"),
                         std::invalid_argument);
    Affinef bad;
    bad.m[2] = nan_f;
    CHECK_THROWS_WITH_AS(inverse(bad), doctest::Contains("NaN or infinite"), std::invalid_argument);
    Affinef skew;
    skew.m[0] = 1e5f;
    skew.m[5] = 1e-5f;
    CHECK_THROWS_WITH_AS(inverse(skew), doctest::Contains("too close to singular"), std::invalid_argument);
}

TEST_CASE("TwoLevel: closest hit and occlusion equal brute force over all instances, bit for bit") {
    // (serial and the default executor: TwoLevel's own parallel steps are executor-generic loops, and each
    // executor's chunking is tested by the builders' tests; CI time)
    SUBCASE("PLOC, indexed, serial and default executor") {
        random_scenes<builder::ploc, prim::indexed>(exec::serial{}, "ploc/serial");
        if constexpr (!std::is_same_v<exec::default_executor, exec::serial>)
            random_scenes<builder::ploc, prim::indexed>(exec::default_executor{}, std::string("ploc/") + executor_name<exec::default_executor>());
    }
    SUBCASE("LBVH, copied") { random_scenes<builder::lbvh, prim::copied>(exec::serial{}, "lbvh/copied"); }
    // (not in sanitized builds: another builder behind the same TwoLevel code)
    if constexpr (!test::sanitized_build) {
        SUBCASE("binned SAH, indexed") { random_scenes<builder::binned_sah, prim::indexed>(exec::serial{}, "binned-sah"); }
    }
}

TEST_CASE("TwoLevel: rays from far away past an instance's box corner (the culling's reach widening)") {
    // Far rays carry an object-space rounding error of about u |origin| (0.1 at 1e6): near a corner of
    // the world box, where the box is tight, only the reach widening of two_level.hpp keeps them.
    const auto plane = plane_mesh();
    TwoLevel<builder::ploc, Node<>, prim::indexed, exec::serial> scene;
    scene.add_object(plane);
    Rng r(31);
    std::size_t hits = 0, bad = 0, rays = 0;
    for (int k = 0; k < 4; ++k) {
        std::vector<Instance<float>> inst(1);
        inst[0].transform = random_transform(r, {float(k) * 1000.0f, 0, 0}, 5, k % 2 == 1);
        scene.set_instances(inst);
        scene.commit();
        const Vec3f corners[4] = {{0, 0, 0}, {4, 0, 0}, {0, 4, 0}, {4, 4, 0}};
        for (std::size_t i = 0; i < sanitizer_scaled(6000); ++i) {
            const Vec3f target = inst[0].transform.point(corners[i % 4]);
            const float dist = 1e6f;
            const Vec3f dir = normalize(Vec3f{r.uniform(-1, 1), r.uniform(-1, 1), r.uniform(-1, 1)});
            const Vec3f jitter = Vec3f{r.uniform(-1, 1), r.uniform(-1, 1), r.uniform(-1, 1)} * (4e-7f * dist);
            Rayf ray{target - dir * dist, {}};
            ray.dir = target + jitter - ray.org;
            const InstanceHit<float> e = reference(scene, ray);
            const InstanceHit<float> h = scene.intersect(ray);
            ++rays;
            hits += bool(e);
            if (!same_instance_hit(scene, h, e, ray) || scene.occluded(ray) != bool(e)) ++bad;
        }
    }
    CHECK_MESSAGE(bad == 0, bad, " of ", rays, " far rays differ from brute force");
    CHECK(hits * 5 > rays);
}

TEST_CASE("TwoLevel: many instances of one object, overlapping, with top leaves of several instances") {
    const auto ball = sphere(6, 12);
    TwoLevelConfig<builder::ploc> cfg;
    cfg.top.leaves.max_leaf_size = 4;
    cfg.top.leaves.cost.ci = 0.1;   // collapse eagerly: leaves of several instances
    TwoLevel<builder::ploc, Node<>, prim::indexed, exec::serial> scene(cfg);
    scene.add_object(ball);
    Rng r(77);
    std::vector<Instance<float>> inst(300);
    for (auto& i : inst) i.transform = random_transform(r, {0, 0, 0}, 6, r.next() % 2 == 0);
    scene.set_instances(inst);
    scene.commit();
    bool multi = false;
    for (const auto& n : scene.top().nodes) multi = multi || n.count > 1;
    CHECK(multi);
    check_scene(scene, 5, "300 balls", 400);
}

TEST_CASE("TwoLevel: an exact tie between instances goes to the larger instance index, in every query") {
    const auto ball = sphere(8, 16);
    auto ball_and_speck = ball;   // the same triangles first, and one far away: a larger box
    ball_and_speck.push_back({{6, 6, 6}, {6.1f, 6, 6}, {6, 6.1f, 6}});
    TwoLevel<builder::ploc, Node<>, prim::indexed, exec::serial> scene;
    scene.add_object(ball);
    scene.add_object(ball_and_speck);
    Rng r(11);
    const Affinef a = random_transform(r, {0, 0, 0}, 1, false), b = random_transform(r, {15, 0, 0}, 1, true);
    // instances 0 and 2 hold the same ball at the same place (the same object rays: the same t, the same
    // triangle); 2's larger box is entered first, so a traversal taking the last hit found would answer 0
    const std::vector<Instance<float>> inst = {{0, a}, {0, b}, {1, a}};
    scene.set_instances(inst);
    scene.commit();
    std::vector<Rayf> rays = tile_rays(scene, 8, 5);
    std::size_t ties = 0, bad = 0;
    for (const Rayf& ray : rays) {
        const InstanceHit<float> h = scene.intersect(ray), e = reference(scene, ray);
        if (!identical(h, e) || !identical(scene.brute_force_intersect(ray), e)) ++bad;
        if (e && e.instance != 1) {
            ++ties;
            if (e.instance != 2) ++bad;
        }
    }
    CHECK(bad == 0);
    CHECK(ties > 10);
    CHECK(packet_mismatches<16>(scene, rays, "ties") == 0);
}

TEST_CASE("TwoLevel: a rigid update only moves instances; object trees are reused untouched") {
    const auto ball = sphere(8, 16);
    const auto soup = random_soup(100, 8, 0.1f);
    TwoLevel<builder::ploc, Node<>, prim::indexed, exec::serial> scene;
    scene.add_object(ball);
    scene.add_object(soup);
    scene.set_instances(random_instances(scene, 20, 3, {0, 0, 0}, 8));
    scene.commit();
    const std::vector<Node<>> nodes0(scene.object_bvh(0).nodes.begin(), scene.object_bvh(0).nodes.end());
    const std::vector<Node<>> nodes1(scene.object_bvh(1).nodes.begin(), scene.object_bvh(1).nodes.end());
    const auto* data0 = scene.object_bvh(0).nodes.data();
    const auto* data1 = scene.object_bvh(1).nodes.data();
    const std::vector<Node<>> top_before(scene.top().nodes.begin(), scene.top().nodes.end());
    Rng r(4);
    for (int frame = 0; frame < 4; ++frame) {
        std::vector<Affinef> moved;
        for (const auto& i : scene.instances()) {
            Affinef m = i.transform;
            m.m[3] += r.uniform(-2, 2);
            m.m[7] += r.uniform(-2, 2);
            moved.push_back(m);
        }
        scene.set_transforms(moved);
        CHECK_FALSE(scene.committed());
        CHECK_THROWS_AS((void)scene.intersect(Rayf{}), std::logic_error);
        scene.commit();
        check_scene(scene, 50 + std::uint64_t(frame), "rigid frame " + std::to_string(frame), 150);
    }
    // Same arrays (no rebuild, no refit: not even reallocated) with the same contents.
    CHECK(scene.object_bvh(0).nodes.data() == data0);
    CHECK(scene.object_bvh(1).nodes.data() == data1);
    CHECK(std::equal(nodes0.begin(), nodes0.end(), scene.object_bvh(0).nodes.begin(),
                     [](const Node<>& a, const Node<>& b) { return a.bounds() == b.bounds() && a.index == b.index && a.count == b.count; }));
    CHECK(std::equal(nodes1.begin(), nodes1.end(), scene.object_bvh(1).nodes.begin(),
                     [](const Node<>& a, const Node<>& b) { return a.bounds() == b.bounds() && a.index == b.index && a.count == b.count; }));
    CHECK_FALSE(top_before[0].bounds() == scene.top().nodes[0].bounds());   // the top level did move
}

TEST_CASE("TwoLevel: a deformed object is refitted (or rebuilt by its policy); others stay") {
    const auto ball = sphere(8, 16);
    const auto plane = plane_mesh();
    TwoLevel<builder::ploc, Node<>, prim::indexed, exec::serial> scene;
    scene.add_object(ball);
    scene.add_object(plane);
    scene.set_instances(random_instances(scene, 16, 6, {0, 0, 0}, 6));
    scene.commit();
    const auto* plane_nodes = scene.object_bvh(1).nodes.data();
    // A small wobble of the ball: refit.
    auto wobble = ball;
    for (std::size_t i = 0; i < wobble.size(); ++i) wobble[i].p0 += Vec3f{0.01f * float(i % 3), 0, 0.005f};
    FrameReport rep = scene.update_object(0, wobble);
    CHECK(rep.decision == Decision::refit);
    CHECK(scene.object_bvh(0).bounds() == [&] { AABBf b; for (auto& t : wobble) b.extend(t.bounds()); return b; }());
    scene.commit();
    check_scene(scene, 60, "wobbled ball");
    // Exploded: the object's policy rebuilds.
    auto blown = ball;   // every triangle off in its own random direction: the refitted SAH grows
    Rng r(12);
    for (auto& t : blown) {
        const Vec3f d = Vec3f{r.uniform(-1, 1), r.uniform(-1, 1), r.uniform(-1, 1)} * 1.5f;
        t.p0 += d; t.p1 += d; t.p2 += d;
    }
    rep = scene.update_object(0, blown);
    CHECK(rep.decision == Decision::rebuild);
    scene.commit();
    check_scene(scene, 61, "exploded ball");
    // Fewer triangles: a topology change.
    blown.resize(blown.size() / 3);
    rep = scene.update_object(0, blown);
    CHECK(rep.reason == Reason::topology);
    CHECK(scene.object_bvh(0).primitive_count == blown.size());
    scene.commit();
    check_scene(scene, 62, "shrunk ball");
    CHECK(scene.object_bvh(1).nodes.data() == plane_nodes);
}

namespace {
/// An indexed (n+1) x (n+1) vertex grid bent into a wave, 2 n^2 triangles sharing vertices.
struct IndexedWave {
    std::vector<Vec3f> vertices;
    std::vector<std::uint32_t> indices;
    std::vector<std::uint16_t> indices16;
    IndexedWave(int n, float phase) {
        for (int i = 0; i <= n; ++i)
            for (int j = 0; j <= n; ++j)
                vertices.push_back({float(i) / float(n), float(j) / float(n), 0.2f * std::sin(float(i + j) * 0.7f + phase)});
        const auto at = [&](int i, int j) { return std::uint32_t(i * (n + 1) + j); };
        for (int i = 0; i < n; ++i)
            for (int j = 0; j < n; ++j)
                for (std::uint32_t v : {at(i, j), at(i + 1, j), at(i + 1, j + 1), at(i, j), at(i + 1, j + 1), at(i, j + 1)}) {
                    indices.push_back(v);
                    indices16.push_back(std::uint16_t(v));
                }
    }
    MeshView<float> view() const { return {std::span<const Vec3f>(vertices), std::span<const std::uint32_t>(indices)}; }
    MeshView<float, std::uint16_t> view16() const {
        return {std::span<const Vec3f>(vertices), std::span<const std::uint16_t>(indices16)};
    }
    std::vector<Trianglef> flat() const { return make_triangles(std::span<const Vec3f>(vertices), std::span<const std::uint32_t>(indices)); }
};
} // namespace

TEST_CASE("TwoLevel: objects from mesh views trace as from their flattened triangles, bit for bit") {
    IndexedWave wave(12, 0.0f), small(5, 1.0f);
    const auto ball = sphere(8, 16);
    using Scene = TwoLevel<builder::ploc, Node<>, prim::indexed, exec::serial>;
    Scene viewed, flat;
    CHECK(viewed.add_object(wave.view()) == 0);
    CHECK(viewed.add_object(small.view16()) == 1);
    CHECK(viewed.add_object(ball) == 2);   // spans and views mix
    auto wave_tris = wave.flat();
    const auto small_tris = small.flat();
    flat.add_object(wave_tris);
    flat.add_object(small_tris);
    flat.add_object(ball);
    CHECK(viewed.object_triangle_count(0) == wave_tris.size());
    CHECK(viewed.object_triangle(1, 3).p2 == small_tris[3].p2);
    CHECK_THROWS_WITH_AS(viewed.object_triangles(0), doctest::Contains("MeshView"), std::logic_error);
    CHECK_THROWS_AS(viewed.object_triangle(1, small_tris.size()), std::invalid_argument);
    const auto same_trees = [&] {
        for (std::uint32_t o = 0; o < 3; ++o) {
            CHECK(viewed.object_bvh(o).nodes.size() == flat.object_bvh(o).nodes.size());
            CHECK(viewed.object_bvh(o).prim_ids == flat.object_bvh(o).prim_ids);
        }
    };
    same_trees();
    const auto instances = random_instances(flat, 20, 71, {0, 0, 0}, 4);
    viewed.set_instances(instances);
    flat.set_instances(instances);
    viewed.commit();
    flat.commit();
    const auto compare = [&](std::uint64_t seed, const std::string& what) {
        std::size_t differ = 0;
        for (const Rayf& ray : scene_rays(flat, sanitizer_scaled(300), seed)) {
            const InstanceHit<float> a = viewed.intersect(ray), b = flat.intersect(ray);
            const bool same = a.instance == b.instance && a.prim == b.prim && same_bits(a.t, b.t) && same_bits(a.u, b.u) &&
                              same_bits(a.v, b.v) && viewed.occluded(ray) == flat.occluded(ray);
            differ += !same;
        }
        CHECK_MESSAGE(differ == 0, what, ": ", differ, " rays differ between the view and the span scene");
        check_scene(viewed, seed + 1, what + " (views)");
    };
    compare(80, "views");
    // The wave moves in place: both refit (or rebuild) alike.
    for (Vec3f& v : wave.vertices) v.z += 0.05f * v.x;
    wave_tris = wave.flat();
    const FrameReport rv = viewed.update_object(0, wave.view());
    const FrameReport rf = flat.update_object(0, std::span<const Trianglef>(wave_tris));
    CHECK(rv.decision == rf.decision);
    same_trees();
    viewed.commit();
    flat.commit();
    compare(90, "moved wave");
    // An object may switch from a view to a span.
    viewed.update_object(1, std::span<const Trianglef>(small_tris));
    CHECK(viewed.object_triangles(1).size() == small_tris.size());
    viewed.commit();
    compare(95, "view then span");
}

TEST_CASE("TwoLevel: empty scenes, empty objects") {
    TwoLevel<> scene;
    scene.commit();
    CHECK(scene.top().empty());
    CHECK_FALSE(scene.intersect(Rayf{{0, 0, -5}, {0, 0, 1}}));
    CHECK_FALSE(scene.occluded(Rayf{{0, 0, -5}, {0, 0, 1}}));
    const std::vector<Trianglef> none;
    scene.add_object(none);
    scene.set_instances(std::vector<Instance<float>>(3));
    scene.commit();
    CHECK(scene.top().empty());
    CHECK(scene.top().excluded == 3);
    CHECK_FALSE(scene.intersect(Rayf{{0, 0, -5}, {0, 0, 1}}));
    // One instance of one triangle.
    const std::vector<Trianglef> one{{{-1, -1, 0}, {1, -1, 0}, {0, 1, 0}}};
    scene.add_object(one);
    std::vector<Instance<float>> inst(1);
    inst[0].object = 1;
    inst[0].transform = Affinef::translation({0, 0, 3});
    scene.set_instances(inst);
    scene.commit();
    const auto h = scene.intersect(Rayf{{0, 0, -5}, {0, 0, 1}});
    REQUIRE(h);
    CHECK(h.t == 8.0f);
    CHECK(h.instance == 0);
    CHECK(h.prim == 0);
    // The padded world box holds the exact one and is not much larger: the rounding padding plus the
    // reach widening folded in for the float top level (two_level.hpp: alpha (B + S), alpha = 256 u (kappa + 1)
    // = 3.05e-5 here, B = 3, S = 8 * 3), about 9e-4 per side.
    const AABBf top = scene.top().bounds();
    CHECK(top.contains(AABBf{{-1, -1, 3}, {1, 1, 3}}));
    CHECK(length(top.max - Vec3f{1, 1, 3}) < 2e-3f);
    CHECK(length(top.min - Vec3f{-1, -1, 3}) < 2e-3f);
    CHECK(length(top.max - Vec3f{1, 1, 3}) > 1e-4f);   // the widening is there
    CHECK_FALSE(scene.intersect(Rayf{{0, 0, -5}, {0, 0, 1}, 0, 7.99f}));   // tmax short of the triangle
    CHECK(scene.occluded(Rayf{{0, 0, -5}, {0, 0, 1}, 0, 8.0f}));
}

TEST_CASE("TwoLevel: bad input is a clear error and leaves the scene as it was") {
    const auto ball = sphere(4, 8);
    TwoLevel<> scene;
    scene.add_object(ball);
    std::vector<Instance<float>> inst(2);
    scene.set_instances(inst);
    scene.commit();
    inst[1].object = 5;
    CHECK_THROWS_WITH_AS(scene.set_instances(inst), doctest::Contains("instances[1].object is 5 but the scene has 1 objects"),
                         std::invalid_argument);
    inst[1].object = 0;
    inst[0].transform.m[0] = 0;
    inst[0].transform.m[1] = 0;
    inst[0].transform.m[2] = 0;
    CHECK_THROWS_WITH_AS(scene.set_instances(inst), doctest::Contains("instances[0].transform is singular"), std::invalid_argument);
    inst[0].transform.m[0] = std::numeric_limits<float>::infinity();
    CHECK_THROWS_WITH_AS(scene.set_instances(inst), doctest::Contains("instances[0].transform has a NaN"), std::invalid_argument);
    CHECK(scene.committed());   // nothing changed
    CHECK(scene.instance_count() == 2);
    const std::vector<Affinef> three(3);
    CHECK_THROWS_WITH_AS(scene.set_transforms(three), doctest::Contains("transforms has 3 entries but the scene has 2 instances"),
                         std::invalid_argument);
    std::vector<Affinef> two(2);
    two[1].m[10] = 0;
    CHECK_THROWS_WITH_AS(scene.set_transforms(two), doctest::Contains("transforms[1] is singular"), std::invalid_argument);
    CHECK(scene.committed());
    CHECK_THROWS_WITH_AS(scene.update_object(3, ball), doctest::Contains("object is 3 but the scene has 1 objects"),
                         std::invalid_argument);
    CHECK_THROWS_AS((void)scene.object_bvh(1), std::invalid_argument);
    CHECK_THROWS_WITH_AS(TwoLevel<>({.objects = {.rebuild_threshold = -2}}), doctest::Contains("rebuild_threshold"),
                         std::invalid_argument);
    // A world box beyond float range.
    std::vector<Affinef> huge(2);
    huge[0].m[0] = huge[0].m[5] = huge[0].m[10] = 1e37f;
    huge[0].m[3] = 3.4e38f;
    scene.set_transforms(huge);
    CHECK_THROWS_WITH_AS(scene.commit(), doctest::Contains("world box of instance 0 overflows"), std::invalid_argument);
}
