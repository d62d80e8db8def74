/// @file io/obj.hpp
/// Wavefront OBJ reader on tinyobjloader (Debian's libtinyobjloader-dev; link
/// tinyobjloader::tinyobjloader). Positions and faces are kept (normals and texture
/// coordinates are not); polygons are fan-triangulated like PLY faces; MTL materials
/// become io::Material with one material id per triangle.
///
/// MTL -> Material mapping:
///   Kd -> diffuse, Ka -> ambient, Ks -> specular, Ns -> shininess, Ni -> ior, illum -> illum,
///   d -> opacity (tinyobjloader turns `Tr` into d = 1 - Tr when `d` is absent),
///   transmission = 1 - d when d < 1; otherwise, for the refraction models illum 6 and 7,
///   the mean of Tf; otherwise 0. (Tf is not used for other models: exporters such as
///   3ds Max write `Tf 1 1 1` on opaque materials.) Values are clamped to [0, 1] where
///   they are fractions.
/// Faces without a material (no `usemtl`, or an unknown name) get an extra material named
/// "default" with Material's defaults, appended only when needed. A file without
/// materials gives an empty `face_material`.
///
/// Errors throw io::LoadError naming the file: missing file, a parse error from
/// tinyobjloader (its error and warning text included), vertex lines with NaN/inf or
/// fewer than three coordinates ("line N"), face indices out of range ("line N"),
/// polygons of more than 255 vertices (tinyobjloader stores counts in a byte).
/// tinyobjloader's warnings (e.g. a missing .mtl file) do not fail the load; they are
/// returned through `warnings` when given.
#pragma once

#include <algorithm>
#include <charconv>
#include <cmath>
#include <cstdint>
#include <cstring>
#include <filesystem>
#include <limits>
#include <span>
#include <istream>
#include <streambuf>
#include <string>
#include <string_view>
#include <vector>

#include "ply.hpp"  // detail::read_file
#include "scene.hpp"

#if __has_include(<tiny_obj_loader.h>)
#include <tiny_obj_loader.h>
#define DYNBVH_HAS_TINYOBJLOADER 1
#else
#define DYNBVH_HAS_TINYOBJLOADER 0
#endif

namespace dynbvh::io {

/// Parses OBJ text held in memory. `name_for_errors` names it in errors; `mtl_dir` is the
/// folder `mtllib` files are looked up in (empty: materials are not loaded, a warning says so).
/// tinyobjloader's warnings are appended to `*warnings` when it is not null.
Mesh read_obj(std::span<const char> bytes, std::string name_for_errors, std::string mtl_dir, std::string* warnings = nullptr);

/// Reads the OBJ file at `path`; `mtllib` files are looked up next to it.
Mesh read_obj(const std::string& path, std::string* warnings = nullptr);

#if DYNBVH_HAS_TINYOBJLOADER
/// The MTL mapping documented above.
inline Material to_material(const tinyobj::material_t& t) {
    auto c01 = [](double v) { return static_cast<float>(std::clamp(v, 0.0, 1.0)); };
    auto rgb = [](const tinyobj::real_t* v) { return Vec3f{static_cast<float>(v[0]), static_cast<float>(v[1]), static_cast<float>(v[2])}; };
    Material m;
    m.name = t.name;
    m.ambient = rgb(t.ambient);
    m.diffuse = rgb(t.diffuse);
    m.specular = rgb(t.specular);
    m.shininess = static_cast<float>(t.shininess);
    m.ior = static_cast<float>(t.ior);
    m.opacity = c01(t.dissolve);
    m.illum = t.illum;
    if (m.opacity < 1) m.transmission = 1 - m.opacity;
    else if (t.illum == 6 || t.illum == 7)
        m.transmission = c01((double(t.transmittance[0]) + double(t.transmittance[1]) + double(t.transmittance[2])) / 3);
    return m;
}
#endif

namespace detail::obj {

/// A read-only streambuf over bytes we already hold (no copy).
struct SpanBuf : std::streambuf {
    explicit SpanBuf(std::span<const char> s) {
        char* b = const_cast<char*>(s.data());  // input only: never written through
        setg(b, b, b + s.size());
    }
};

/// Calls f(line_number, text) for every line of `bytes` (text without '\n' and '\r').
template <class F> void for_each_line(std::span<const char> bytes, F&& f) {
    const char* p = bytes.data();
    const char* const end = p + bytes.size();
    for (std::size_t line = 1; p < end; ++line) {
        const char* eol = static_cast<const char*>(std::memchr(p, '\n', static_cast<std::size_t>(end - p)));
        if (!eol) eol = end;
        std::string_view text(p, static_cast<std::size_t>(eol - p));
        if (!text.empty() && text.back() == '\r') text.remove_suffix(1);
        if (!f(line, text)) return;
        p = eol + 1;
    }
}

/// The text after a keyword `v`, `f`, ... when `text` is such a line, else nullopt-like empty flag.
inline bool keyword(std::string_view text, std::string_view key, std::string_view& rest) {
    std::size_t i = 0;
    while (i < text.size() && (text[i] == ' ' || text[i] == '\t')) ++i;
    if (text.substr(i, key.size()) != key) return false;
    i += key.size();
    if (i >= text.size() || (text[i] != ' ' && text[i] != '\t')) return false;
    rest = text.substr(i);
    return true;
}

/// tinyobjloader reads "nan", "inf" or a missing coordinate as 0: find such `v` lines first.
inline void check_vertex_lines(std::span<const char> bytes, const std::string& file) {
    for_each_line(bytes, [&](std::size_t line, std::string_view text) {
        std::string_view rest;
        if (!keyword(text, "v", rest)) return true;
        int tokens = 0;
        bool in_token = false;
        for (char c : rest) {
            if (c == '#') break;
            const bool space = c == ' ' || c == '\t';
            if (!space && !in_token) ++tokens;
            in_token = !space;
            const bool alpha = (c >= 'a' && c <= 'z') || (c >= 'A' && c <= 'Z');
            if (alpha && c != 'e' && c != 'E')
                throw LoadError(file, "line " + std::to_string(line), "vertex coordinate is not a finite number: '" + std::string(text) + "'");
        }
        if (tokens < 3) throw LoadError(file, "line " + std::to_string(line), "vertex has fewer than 3 coordinates");
        return true;
    });
}

/// Line of the `n`-th `v` line (0-based), for errors found after parsing.
inline std::size_t nth_vertex_line(std::span<const char> bytes, std::size_t n) {
    std::size_t found = 0, seen = 0;
    for_each_line(bytes, [&](std::size_t line, std::string_view text) {
        std::string_view rest;
        if (keyword(text, "v", rest) && seen++ == n) { found = line; return false; }
        return true;
    });
    return found;
}

/// First `f` line with an index that resolves outside [0, vertex_count); 0 if none.
inline std::size_t bad_face_line(std::span<const char> bytes, std::int64_t vertex_count) {
    std::size_t found = 0;
    std::int64_t seen = 0;
    for_each_line(bytes, [&](std::size_t line, std::string_view text) {
        std::string_view rest;
        if (keyword(text, "v", rest)) { ++seen; return true; }
        if (!keyword(text, "f", rest)) return true;
        for (std::size_t i = 0; i < rest.size();) {
            while (i < rest.size() && (rest[i] == ' ' || rest[i] == '\t')) ++i;
            if (i >= rest.size() || rest[i] == '#') break;
            std::int64_t idx = 0;
            const auto r = std::from_chars(rest.data() + i, rest.data() + rest.size(), idx);
            if (r.ec == std::errc{}) {
                const std::int64_t v = idx > 0 ? idx - 1 : seen + idx;
                if (idx == 0 || v < 0 || v >= vertex_count) { found = line; return false; }
            }
            while (i < rest.size() && rest[i] != ' ' && rest[i] != '\t') ++i;
        }
        return true;
    });
    return found;
}

inline std::string where_line(std::size_t line) { return line ? "line " + std::to_string(line) : std::string(); }

} // namespace detail::obj

#if DYNBVH_HAS_TINYOBJLOADER

inline Mesh read_obj(std::span<const char> bytes, std::string file, std::string mtl_dir, std::string* warnings) {
    using namespace detail::obj;
    check_vertex_lines(bytes, file);

    tinyobj::attrib_t attrib;
    std::vector<tinyobj::shape_t> shapes;
    std::vector<tinyobj::material_t> materials;
    std::string warn, err;
    SpanBuf buf(bytes);
    std::istream in(&buf);
    if (!mtl_dir.empty() && mtl_dir.back() != '/') mtl_dir += '/';
    tinyobj::MaterialFileReader mtl_reader(mtl_dir);
    const bool ok = tinyobj::LoadObj(&attrib, &shapes, &materials, &warn, &err, &in, mtl_dir.empty() ? nullptr : &mtl_reader,
                                     /*triangulate=*/false);
    auto trim = [](std::string s) {
        while (!s.empty() && (s.back() == '\n' || s.back() == ' ' || s.back() == '.')) s.pop_back();
        for (auto& c : s) if (c == '\n') c = ';';
        return s;
    };
    if (!ok || !err.empty())
        throw LoadError(file, "", "tinyobjloader: " + trim(err) + (warn.empty() ? "" : " (warnings: " + trim(warn) + ")"));
    if (warnings && !warn.empty()) *warnings += warn;

    Mesh m;
    const std::size_t nv = attrib.vertices.size() / 3;
    if (nv > std::numeric_limits<std::uint32_t>::max()) throw LoadError(file, "", "more than 2^32-1 vertices");
    m.vertices.resize(nv);
    for (std::size_t i = 0; i < nv; ++i) {
        const Vec3f v{static_cast<float>(attrib.vertices[3 * i]), static_cast<float>(attrib.vertices[3 * i + 1]),
                      static_cast<float>(attrib.vertices[3 * i + 2])};
        if (!dynbvh::is_finite(v))
            throw LoadError(file, where_line(nth_vertex_line(bytes, i)), "vertex " + std::to_string(i + 1) + " is not finite (or overflows float)");
        m.vertices[i] = v;
    }

    const bool with_materials = !materials.empty();
    for (const auto& t : materials) m.materials.push_back(to_material(t));
    std::uint32_t default_material = ~0u;
    auto material_of = [&](int id) -> std::uint32_t {
        if (id >= 0 && static_cast<std::size_t>(id) < materials.size()) return static_cast<std::uint32_t>(id);
        if (default_material == ~0u) {
            default_material = static_cast<std::uint32_t>(m.materials.size());
            Material d;
            d.name = "default";
            m.materials.push_back(d);
        }
        return default_material;
    };

    for (const auto& s : shapes) {
        const auto& mesh = s.mesh;
        std::size_t offset = 0;
        for (std::size_t f = 0; f < mesh.num_face_vertices.size(); ++f) {
            const std::size_t n = mesh.num_face_vertices[f];
            if (offset + n > mesh.indices.size()) break;  // count wrapped (> 255 vertices): caught below
            const std::uint32_t mat = with_materials ? material_of(f < mesh.material_ids.size() ? mesh.material_ids[f] : -1) : 0;
            for (std::size_t k = 0; k < n; ++k) {
                const int vi = mesh.indices[offset + k].vertex_index;
                if (vi < 0 || static_cast<std::size_t>(vi) >= nv)
                    throw LoadError(file, where_line(bad_face_line(bytes, static_cast<std::int64_t>(nv))),
                                    "face index out of range: " + (vi < 0 ? std::string("before the first vertex")
                                                                          : std::to_string(vi + 1)) +
                                        " (there are " + std::to_string(nv) + " vertices)");
            }
            for (std::size_t k = 2; k < n; ++k) {
                m.faces.push_back({static_cast<std::uint32_t>(mesh.indices[offset].vertex_index),
                                   static_cast<std::uint32_t>(mesh.indices[offset + k - 1].vertex_index),
                                   static_cast<std::uint32_t>(mesh.indices[offset + k].vertex_index)});
                if (with_materials) m.face_material.push_back(mat);
            }
            offset += n;
        }
        if (offset != mesh.indices.size())
            throw LoadError(file, "", "shape '" + s.name + "' has a polygon with more than 255 vertices (not supported by tinyobjloader)");
    }
    return m;
}

inline Mesh read_obj(const std::string& path, std::string* warnings) {
    const auto bytes = detail::read_file(path);
    std::string dir = std::filesystem::path(path).parent_path().string();
    if (dir.empty()) dir = ".";
    return read_obj(bytes.span(), path, dir, warnings);
}

#else

inline Mesh read_obj(std::span<const char>, std::string file, std::string, std::string*) {
    throw LoadError(std::move(file), "", "OBJ support needs tinyobjloader (tiny_obj_loader.h was not found at build time)");
}
inline Mesh read_obj(const std::string& path, std::string*) {
    throw LoadError(path, "", "OBJ support needs tinyobjloader (tiny_obj_loader.h was not found at build time)");
}

#endif

} // namespace dynbvh::io
