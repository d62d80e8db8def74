// Adversarial rays (issue 5): axis-parallel with +0 / -0 components, grazing, through shared edges and
// vertices of closed meshes, lying in box planes, origins on box faces and on triangles, tmin == tmax,
// huge and tiny tmax, NaN / infinite / empty rays. Every builder x every executor answers exactly what
// brute force answers with the same (robust) intersector; exact expected values on a cube.
#include "robust_support.hpp"

#include <cmath>
#include <limits>
#include <vector>

using namespace dynbvh;
using namespace dynbvh::test;

TEST_CASE("adversarial rays on closed meshes and soups: every builder x executor == brute force") {
    const std::size_t per_kind = sanitized() ? 60 : 300;
    check_case("random soup", random_soup(600, 11), per_kind, 1);
    check_case("long thin", long_thin(600, 12), per_kind, 2);
    check_case("cube 8x8 (closed)", cube_mesh(8).triangles(), per_kind, 3);
    check_case("sphere 16x32 (closed)", sphere_mesh(16, 32).triangles(), per_kind, 4);
    check_case("torus 32x16 (closed)", torus_mesh(1.0, 0.4, 32, 16).triangles(), per_kind, 5);
    if (have_data("meshes/bun_zipper.ply"))
        check_case("bunny", io::read_ply(data_path("meshes/bun_zipper.ply")).triangles(), sanitized() ? 4 : 30, 6);
    else
        MESSAGE("skipping the bunny: " << data_path("meshes/bun_zipper.ply") << " is absent");
}

namespace {

/// The 2x2-per-face cube [-1, 1]^3: vertices at -1, 0, 1 on every axis (face centres are vertices of valence 4 or 8).
const std::vector<Trianglef>& cube() {
    static const std::vector<Trianglef> tris = cube_mesh(2).triangles();
    return tris;
}

/// Whether triangle `prim` of the cube lies in the face where coordinate `axis` equals `side`.
bool on_face(std::uint32_t prim, std::size_t axis, float side) {
    if (prim >= cube().size()) return false;
    const Trianglef& t = cube()[prim];
    return t.p0[axis] == side && t.p1[axis] == side && t.p2[axis] == side;
}

struct Expect {
    Rayf ray;
    bool hit;
    float t = 0;
    std::size_t face_axis = 0;
    float face_side = 0;
    const char* what;
};

/// Hand-made rays with exactly known answers, for every axis, direction sign and signed zero pattern.
std::vector<Expect> expectations() {
    std::vector<Expect> e;
    const float zero[2] = {0.0f, -0.0f};
    const float fmax = std::numeric_limits<float>::max();
    for (std::size_t a = 0; a < 3; ++a) {
        const std::size_t b = (a + 1) % 3, c = (a + 2) % 3;
        for (float s : {1.0f, -1.0f})
            for (int zb = 0; zb < 2; ++zb)
                for (int zc = 0; zc < 2; ++zc) {
                    Vec3f d;
                    d[a] = s;
                    d[b] = zero[zb];
                    d[c] = zero[zc];
                    auto ray = [&](float ob, float oc, float oa, float tmin = 0, float tmax = finf) {
                        Rayf r;
                        r.org[a] = oa;
                        r.org[b] = ob;
                        r.org[c] = oc;
                        r.dir = d;
                        r.tmin = tmin;
                        r.tmax = tmax;
                        return r;
                    };
                    const float near = -s, far = s, start = -5 * s;   // entry face, exit face, origin
                    // Inside a face, at a face-centre vertex, along the plane of a side face (grazing its box),
                    // along an edge line of the cube (through a corner): entry at t = 4 on the near face.
                    e.push_back({ray(0.25f, 0.5f, start), true, 4, a, near, "face interior"});
                    e.push_back({ray(0.0f, 0.0f, start), true, 4, a, near, "through a face-centre vertex"});
                    e.push_back({ray(0.5f, 0.0f, start), true, 4, a, near, "through a shared edge"});
                    e.push_back({ray(1.0f, 0.5f, start), true, 4, a, near, "in the plane of a side face"});
                    e.push_back({ray(-1.0f, -1.0f, start), true, 4, a, near, "along an edge line, through a corner"});
                    e.push_back({ray(1.0f, 1.0000001f, start), false, 0, a, near, "one ulp outside a side face"});
                    // Origins on the surface: t = 0 on the face itself; from tmin > 0 the far face at t = 2.
                    e.push_back({ray(0.25f, 0.5f, near), true, 0, a, near, "origin on a face"});
                    e.push_back({ray(0.0f, 0.0f, near), true, 0, a, near, "origin at a vertex"});
                    e.push_back({ray(0.25f, 0.5f, near, std::numeric_limits<float>::denorm_min()), true, 2, a, far,
                                 "origin on a face, tmin = denorm_min"});
                    e.push_back({ray(-1.0f, 0.5f, near, 1e-30f), true, 2, a, far, "origin on a cube edge, tmin = 1e-30"});
                    // Intervals: tmin == tmax at the hit, one ulp off it; huge and tiny tmax; negative tmin.
                    e.push_back({ray(0.25f, 0.5f, start, 4, 4), true, 4, a, near, "tmin == tmax == hit"});
                    e.push_back({ray(0.25f, 0.5f, start, std::nextafter(4.0f, 5.0f), std::nextafter(4.0f, 5.0f)), false, 0, a,
                                 near, "tmin == tmax one ulp after the hit"});
                    e.push_back({ray(0.25f, 0.5f, start, 0, std::nextafter(4.0f, 0.0f)), false, 0, a, near,
                                 "tmax one ulp before the hit"});
                    e.push_back({ray(0.25f, 0.5f, start, 0, fmax), true, 4, a, near, "tmax = FLT_MAX"});
                    e.push_back({ray(0.25f, 0.5f, start, 0, 1e30f), true, 4, a, near, "tmax = 1e30"});
                    e.push_back({ray(0.25f, 0.5f, start, 0, 1e-30f), false, 0, a, near, "tmax = 1e-30"});
                    e.push_back({ray(0.25f, 0.5f, 0.0f, -finf, finf), true, -1, a, near, "from the centre, tmin = -inf"});
                    e.push_back({ray(0.25f, 0.5f, 0.0f, -fmax, fmax), true, -1, a, near, "from the centre, tmin = -FLT_MAX"});
                    e.push_back({ray(0.25f, 0.5f, 0.0f, 0, finf), true, 1, a, far, "from the centre"});
                    e.push_back({ray(0.25f, 0.5f, start, 0, 0), false, 0, a, near, "tmax = 0 outside"});
                    e.push_back({ray(0.25f, 0.5f, near, 0, 0), true, 0, a, near, "tmin = tmax = 0 on the surface"});
                }
    }
    // Rays that cannot be traced: no hit, whatever the scene.
    const Rayf good{{0.25f, 0.5f, -5}, {0, 0, 1}};
    for (std::size_t k = 0; k < 3; ++k) {
        for (float bad : {fnan, finf, -finf}) {
            Rayf r = good;
            r.org[k] = bad;
            e.push_back({r, false, 0, 0, 0, "non-finite origin"});
            r = good;
            r.dir[k] = bad;
            e.push_back({r, false, 0, 0, 0, "non-finite direction"});
        }
    }
    for (Rayf r : {Rayf{good.org, {0, 0, 0}}, Rayf{good.org, {-0.0f, 0.0f, -0.0f}}, Rayf{good.org, good.dir, fnan, finf},
                   Rayf{good.org, good.dir, 0, fnan}, Rayf{good.org, good.dir, 5, 4}, Rayf{good.org, good.dir, finf, finf},
                   Rayf{good.org, good.dir, -finf, -finf}})
        e.push_back({r, false, 0, 0, 0, "zero direction, NaN, empty or infinite interval"});
    return e;
}

} // namespace

TEST_CASE("exact answers on a cube: signed zeros, shared edges and vertices, box planes, intervals, NaN") {
    const auto& tris = cube();
    const auto cases = expectations();
    std::size_t fast_wrong = 0, checked = 0;
    for (const Expect& x : cases) {
        CAPTURE(x.what);
        CAPTURE(describe(x.ray));
        const Hitf b = brute_force_intersect(std::span<const Trianglef>(tris), x.ray);
        CHECK(bool(b) == x.hit);
        if (b && x.hit) {
            CHECK(b.t == x.t);
            CHECK(on_face(b.prim, x.face_axis, x.face_side));
        }
    }
    for_each_executor([&](auto ex) {
        const std::string executor = executor_name<decltype(ex)>();
        CAPTURE(executor);
        for_each_builder(tris, ex, [&](std::size_t builder, const auto& bvh, bool single) {
            const std::string builder_name = builder_names[builder];
            CAPTURE(builder_name);
            REQUIRE(structure_problems(bvh, tris, single) == "");
            for (const Expect& x : cases) {
                CAPTURE(x.what);
                CAPTURE(describe(x.ray));
                const Hitf h = intersect(bvh, tris, x.ray);
                CHECK(bool(h) == x.hit);
                CHECK(occluded(bvh, tris, x.ray) == x.hit);
                if (h && x.hit) {
                    CHECK(h.t == x.t);
                    CHECK(on_face(h.prim, x.face_axis, x.face_side));
                }
                const Hitf f = intersect<trace::fast>(bvh, tris, x.ray);
                fast_wrong += (bool(f) != x.hit || (f && f.t != x.t)) ? 1 : 0;
                ++checked;
            }
        });
    });
    MESSAGE("[robustness] cube with exact answers: " << checked << " (ray, tree) pairs; trace::fast wrong on " << fast_wrong);
}

TEST_CASE("rays that cannot be traced never hit and never crash, on every tree") {
    // Also on an empty tree and a tree of one triangle.
    const std::vector<Trianglef> none;
    const std::vector<Trianglef> one{{{0, 0, 0}, {1, 0, 0}, {0, 1, 0}}};
    const auto cases = expectations();
    for (const auto* tris : {&none, &one, &cube()}) {
        for_each_executor([&](auto ex) {
            for_each_builder(*tris, ex, [&](std::size_t builder, const auto& bvh, bool) {
                const std::string builder_name = builder_names[builder];
                CAPTURE(builder_name);
                for (const Expect& x : cases) {
                    if (traceable(x.ray)) continue;
                    CAPTURE(describe(x.ray));
                    CHECK_FALSE(intersect(bvh, *tris, x.ray));
                    CHECK_FALSE(occluded(bvh, *tris, x.ray));
                    CHECK_FALSE(intersect<trace::fast>(bvh, *tris, x.ray));
                    CHECK_FALSE(occluded<trace::fast>(bvh, *tris, x.ray));
                }
            });
        });
    }
}
