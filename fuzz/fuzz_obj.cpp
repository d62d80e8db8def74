// libFuzzer target for the OBJ reader (io/obj.hpp on tinyobjloader): any bytes either load into a
// consistent Mesh or throw io::LoadError. Materials are not loaded (no mtl directory), so nothing is
// read from disk. Build and run: fuzz/run.sh (or tools/fuzz.sh).
#include <dynbvh/io/obj.hpp>

#include <cstddef>
#include <cstdint>
#include <cstdlib>
#include <span>
#include <string>

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
    const std::span<const char> bytes(reinterpret_cast<const char*>(data), size);
    try {
        std::string warnings;
        const dynbvh::io::Mesh m = dynbvh::io::read_obj(bytes, "fuzz.obj", "", &warnings);
        for (const auto& f : m.faces)
            for (auto i : f)
                if (i >= m.vertices.size()) std::abort();
        for (const auto& v : m.vertices)
            if (!dynbvh::is_finite(v)) std::abort();
        if (!m.face_material.empty() && m.face_material.size() != m.faces.size()) std::abort();
        for (auto id : m.face_material)
            if (id >= m.materials.size()) std::abort();
    } catch (const dynbvh::io::LoadError&) {
    }
    return 0;
}
