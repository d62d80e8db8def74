// The study's grouping of a frame's objects into two-level objects (bench/study/object_groups.hpp):
// which objects go together, their object-space triangles and frame indices, and when a later frame
// still fits; on BART Robots (when ../shared/data is present) that the bodies stay rigid over frames.
#include <doctest/doctest.h>

#include <cmath>
#include <vector>

#include <dynbvh/io/bart.hpp>

#include "object_groups.hpp"
#include "support.hpp"

using namespace dynbvh;
using dynbvh::study::GroupedObjects;
using dynbvh::test::data_path;
using dynbvh::test::have_data;

namespace {
io::Transform translation(float x, float y, float z) {
    io::Transform t;
    t.m[12] = x;
    t.m[13] = y;
    t.m[14] = z;
    return t;
}
io::ObjectInstance object(std::uint32_t first, std::uint32_t count, bool animated, io::Transform t, std::uint32_t body) {
    return {.name = "o" + std::to_string(first), .first_triangle = first, .triangle_count = count, .transform = t,
            .animated = animated, .rigid_body = body};
}
} // namespace

TEST_CASE("object groups: static objects together, one rigid body together, the rest alone") {
    const io::Transform a = translation(1, 2, 3), b = translation(-4, 0, 0);
    // triangles 0..9: static 0-1, body 7 at a: 2-3 and 6, body 7 at b: 4, no body: 5, deforming: 7-8, static 9
    std::vector<io::ObjectInstance> objects = {
        object(0, 2, false, {}, io::no_rigid_body), object(2, 2, true, a, 7), object(4, 1, true, b, 7),
        object(5, 1, true, a, io::no_rigid_body),   object(6, 1, true, a, 7), object(7, 2, true, {}, io::no_rigid_body),
        object(9, 0, true, a, 3),                   object(9, 1, false, b, 2)};
    std::vector<Trianglef> tris(10);
    for (std::size_t i = 0; i < tris.size(); ++i) {
        const float f = float(i);
        tris[i] = {{f, 0, 0}, {f, 1, 0}, {f, 0, 1}};
    }
    const GroupedObjects g(objects, tris.size());
    const auto& gs = g.groups();
    REQUIRE(gs.size() == 5);
    CHECK(gs[0].fixed);   // the static objects, in frame order
    CHECK(gs[0].members == std::vector<std::uint32_t>{0, 7});
    CHECK(gs[0].triangles == 3);
    CHECK(gs[1].members == std::vector<std::uint32_t>{1, 4});   // body 7 at a
    CHECK(gs[2].members == std::vector<std::uint32_t>{2});      // body 7 at b: another transform
    CHECK(gs[3].members == std::vector<std::uint32_t>{3});      // no body
    CHECK(gs[4].members == std::vector<std::uint32_t>{5});      // identity transform: deforming
    CHECK(gs[4].deforming);
    CHECK((g.run(4) == std::pair<std::uint32_t, std::uint32_t>{7, 2}));
    for (std::size_t k = 0; k < 4; ++k) CHECK_FALSE(gs[k].deforming);
    CHECK(g.transform(0, objects).m == Affine<float>{}.m);
    CHECK(g.transform(1, objects).m == study::affine_of(a).m);

    // Object space: through the inverse of the group's transform, every member's triangles in order.
    std::vector<Trianglef> local;
    std::vector<std::uint32_t> index;
    g.object_space(1, objects, tris, local, index);
    CHECK(index == std::vector<std::uint32_t>{2, 3, 6});
    for (std::size_t k = 0; k < local.size(); ++k) {
        CHECK(local[k].p0.x == tris[index[k]].p0.x - 1);
        CHECK(local[k].p1.y == tris[index[k]].p1.y - 2);
        CHECK(local[k].p2.z == tris[index[k]].p2.z - 3);
    }
    g.object_space(0, objects, tris, local, index);   // fixed: world space as given
    CHECK(index == std::vector<std::uint32_t>{0, 1, 9});
    CHECK(local[2].p1 == tris[9].p1);
    g.object_space(4, objects, tris, local, index);
    CHECK(index == std::vector<std::uint32_t>{7, 8});

    // A later frame fits while runs and each body's shared transform hold.
    CHECK(g.holds(objects, tris.size()));
    auto moved = objects;
    moved[1].transform = moved[4].transform = translation(5, 5, 5);   // the body moves as one
    moved[3].transform = b;
    CHECK(g.holds(moved, tris.size()));
    moved[4].transform = translation(5, 5, 6);   // its parts diverge
    CHECK_FALSE(g.holds(moved, tris.size()));
    auto regrown = objects;
    regrown[3].triangle_count = 2;
    regrown[4].first_triangle = 7;
    CHECK_FALSE(g.holds(regrown, tris.size()));
    CHECK_FALSE(g.holds(std::span(objects).first(7), tris.size()));

    // Objects that do not tile the frame: the whole frame is one deforming group.
    objects[3].first_triangle = 6;
    const GroupedObjects whole(objects, tris.size());
    REQUIRE(whole.groups().size() == 1);
    CHECK(whole.groups()[0].deforming);
    CHECK((whole.run(0) == std::pair<std::uint32_t, std::uint32_t>{0, 10}));
    CHECK(whole.holds(objects, tris.size()));
    CHECK_FALSE(whole.holds(objects, 11));
    CHECK(GroupedObjects({}, 0).groups().empty());
}

TEST_CASE("object groups: BART Robots' rigid bodies stay rigid over its frames") {
    const std::string path = data_path("bart/robot/Robot.aff");
    if (!have_data("bart/robot/Robot.aff")) {
        MESSAGE("BART data absent, skipped: " << path);
        return;
    }
    auto scene = io::load_bart(path);
    io::Frame f0;
    scene->frame(0, f0);
    const GroupedObjects g(f0.objects, f0.triangles.size());
    const auto& gs = g.groups();
    CHECK(gs.size() < f0.objects.size() / 4);   // 1849 objects in about 220 bodies
    std::vector<std::vector<Trianglef>> local(gs.size());
    std::vector<std::vector<std::uint32_t>> index(gs.size());
    for (std::size_t k = 0; k < gs.size(); ++k) g.object_space(k, f0.objects, f0.triangles, local[k], index[k]);
    // Each later frame: the groups still fit, and each body's object-space triangles placed by its
    // transform are that frame's triangles (up to the rounding of the two transformations).
    for (std::size_t frame : {1u, 37u, 400u, 799u}) {
        CAPTURE(frame);
        io::Frame f;
        scene->frame(frame, f);
        REQUIRE(g.holds(f.objects, f.triangles.size()));
        std::size_t bad = 0;
        for (std::size_t k = 0; k < gs.size(); ++k) {
            const Affine<float> m = g.transform(k, f.objects);
            for (std::size_t t = 0; t < local[k].size(); ++t) {
                const Trianglef& w = f.triangles[index[k][t]];
                if (std::isnan(w.p0.x)) continue;   // hidden this frame
                const Vec3f p = m.point(local[k][t].p1);
                const float scale = 1 + std::max({std::abs(w.p1.x), std::abs(w.p1.y), std::abs(w.p1.z)});
                bad += !(std::abs(p.x - w.p1.x) <= 1e-4f * scale && std::abs(p.y - w.p1.y) <= 1e-4f * scale &&
                         std::abs(p.z - w.p1.z) <= 1e-4f * scale);
            }
        }
        CHECK(bad == 0);
    }
}
