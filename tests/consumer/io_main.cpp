// The loaders through dynbvh::io (+ dynbvh::omp): reads quad.obj (one quad, fan-triangulated, material
// "red" from quad.mtl) with read_obj and as a 1-frame scene with open_frames, builds, traces one ray
// into each triangle.
#include <dynbvh/io/frames.hpp>
#include <dynbvh/io/obj.hpp>
#include <dynbvh/lbvh.hpp>
#include <dynbvh/traverse.hpp>

#include <cstdio>
#include <exception>

int main(int argc, char** argv) {
    if (argc != 2) {
        std::fprintf(stderr, "usage: consumer_io quad.obj\n");
        return 2;
    }
    try {
        using namespace dynbvh;
        const io::Mesh mesh = io::read_obj(argv[1]);
        bool ok = mesh.faces.size() == 2 && mesh.vertices.size() == 4 && !mesh.materials.empty() &&
                  mesh.materials[0].name == "red" && mesh.materials[0].diffuse == Vec3f{1, 0, 0};
        io::Frame f;
        io::open_frames(argv[1])->frame(0, f);
        ok = ok && f.triangles.size() == 2;
        const auto bvh = lbvh::build(f.triangles, {}, exec::default_executor{});
        // The fan (1 2 3), (1 3 4) of the unit square: (0.75, 0.25) is in the first, (0.25, 0.75) in the second.
        const auto a = intersect(bvh, f.triangles, Rayf{.org = {0.75f, 0.25f, 1}, .dir = {0, 0, -1}});
        const auto b = intersect(bvh, f.triangles, Rayf{.org = {0.25f, 0.75f, 1}, .dir = {0, 0, -1}});
        ok = ok && a && a.prim == 0 && a.t == 1.0f && b && b.prim == 1 && b.t == 1.0f;
        std::printf("consumer_io: %s: %zu triangles, material '%s', hits prim %u and %u: %s\n", argv[1],
                    f.triangles.size(), mesh.materials.empty() ? "" : mesh.materials[0].name.c_str(), a.prim, b.prim,
                    ok ? "ok" : "WRONG");
        return ok ? 0 : 1;
    } catch (const std::exception& e) {
        std::fprintf(stderr, "consumer_io: %s\n", e.what());
        return 1;
    }
}
