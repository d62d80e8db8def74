// libFuzzer target for the PLY reader (io/ply.hpp): any bytes either load into a consistent Mesh or
// throw io::LoadError. Anything else (a crash, a sanitizer report, another exception) is a bug.
// Build and run: fuzz/run.sh (or tools/fuzz.sh).
#include <dynbvh/io/ply.hpp>

#include <cstddef>
#include <cstdint>
#include <cstdlib>
#include <span>

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
    const std::span<const char> bytes(reinterpret_cast<const char*>(data), size);
    try {
        const dynbvh::io::Mesh m = dynbvh::io::read_ply(bytes, "fuzz.ply");
        // The reader's promises: indices in range, finite vertices.
        for (const auto& f : m.faces)
            for (auto i : f)
                if (i >= m.vertices.size()) std::abort();
        for (const auto& v : m.vertices)
            if (!dynbvh::is_finite(v)) std::abort();
        // A mesh that loads must survive a round trip through the writer.
        if (!m.vertices.empty() && m.vertices.size() < 4096) {
            const std::string text = dynbvh::io::to_ply(m, dynbvh::io::PlyEncoding::ascii);
            const dynbvh::io::Mesh back = dynbvh::io::read_ply(std::span<const char>(text.data(), text.size()), "roundtrip.ply");
            if (back.vertices != m.vertices || back.faces != m.faces) std::abort();
        }
    } catch (const dynbvh::io::LoadError&) {
    }
    return 0;
}
