// SPDX-License-Identifier: MIT
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
/// Before tinyobjloader sees the text, a leading UTF-8 byte-order mark is skipped and a
/// backslash at the end of a line joins it with the next (OBJ's line continuation); line
/// numbers in errors are those of the file (the first line of a joined line).
///
/// Errors throw io::LoadError naming the file: missing file, a directory, a file with
/// neither vertices nor faces (e.g. a text file renamed .obj), a parse error from
/// tinyobjloader (its error and warning text included), and, with "line N": a vertex
/// coordinate that is not wholly a finite number (`1,5`, `1.0.5`, `1e5e5`, `nan`, `inf`;
/// the text is quoted) or overflows float, fewer than three coordinates, a face index that
/// is not wholly an integer, is at or beyond 2^31 (checked on the text, before any integer
/// could wrap), or resolves outside the vertices (relative indices before the first
/// vertex included); polygons of more than 255 vertices (tinyobjloader stores counts in
/// a byte). Texture and normal coordinates (`vt`, `vn`) are not used and not checked;
/// the texture/normal parts of face indices are checked as integers below 2^31.
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
/// 1 when tinyobjloader's header was found (read_obj needs it: link dynbvh::io), else 0 (read_obj throws).
#define DYNBVH_HAS_TINYOBJLOADER 1
#else
/// 1 when tinyobjloader's header was found (read_obj needs it: link dynbvh::io), else 0 (read_obj throws).
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

/// The text tinyobjloader and the checks read: the file's bytes without a leading UTF-8 byte-order
/// mark, with every backslash-newline continuation replaced by a space (copied only when the file
/// has one), and the file's line number of each line of the result.
struct Text {
    std::span<const char> raw;                ///< the file's bytes after the byte-order mark
    std::string joined;                       ///< the joined text, when `raw` has continuations
    std::vector<std::size_t> first_line;      ///< file line of line k + 1 of bytes(); empty: the same
    std::span<const char> bytes() const { return first_line.empty() ? raw : std::span<const char>(joined.data(), joined.size()); }
    std::size_t file_line(std::size_t line) const {
        return first_line.empty() || line == 0 || line > first_line.size() ? line : first_line[line - 1];
    }
};

inline Text normalise(std::span<const char> bytes) {
    Text t;
    if (bytes.size() >= 3 && std::memcmp(bytes.data(), "\xEF\xBB\xBF", 3) == 0) bytes = bytes.subspan(3);
    t.raw = bytes;
    if (bytes.empty()) return t;
    // Continuations: a '\\' right before "\n" or "\r\n".
    bool any = false;
    for (const char* p = bytes.data(), *end = p + bytes.size(); !any;) {
        p = static_cast<const char*>(std::memchr(p, '\\', static_cast<std::size_t>(end - p)));
        if (!p) break;
        ++p;
        any = (p < end && *p == '\n') || (end - p >= 2 && p[0] == '\r' && p[1] == '\n');
    }
    if (!any) return t;
    t.joined.reserve(bytes.size());
    std::size_t line = 1;
    t.first_line.push_back(1);
    for (std::size_t i = 0; i < bytes.size(); ++i) {
        const char c = bytes[i];
        if (c == '\\') {
            std::size_t j = i + 1;
            if (j < bytes.size() && bytes[j] == '\r' && j + 1 < bytes.size() && bytes[j + 1] == '\n') ++j;
            if (j < bytes.size() && bytes[j] == '\n') {  // joined: the logical line goes on
                t.joined += ' ';
                ++line;
                i = j;
                continue;
            }
        }
        t.joined += c;
        if (c == '\n') t.first_line.push_back(++line);
    }
    return t;
}

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

/// Calls f(token) for the blank-separated tokens of `rest` before a '#' comment.
template <class F> void for_each_token(std::string_view rest, F&& f) {
    std::size_t i = 0;
    for (;;) {
        while (i < rest.size() && (rest[i] == ' ' || rest[i] == '\t')) ++i;
        if (i >= rest.size() || rest[i] == '#') return;
        const std::size_t b = i;
        while (i < rest.size() && rest[i] != ' ' && rest[i] != '\t' && rest[i] != '#') ++i;
        f(rest.substr(b, i - b));
    }
}

/// Whether `tok` is wholly a finite decimal number ([+|-]digits[.digits][e[+|-]digits]); its value in `out`.
/// from_chars stops at the first character that cannot continue the number, so "1,5", "1.0.5" and
/// "1e5e5" are caught by the end check; it also accepts "nan" and "inf", caught by isfinite.
inline bool whole_number(std::string_view tok, double& out) {
    if (!tok.empty() && tok.front() == '+') tok.remove_prefix(1);
    if (tok.empty() || tok.front() == '+') return false;
    const auto r = std::from_chars(tok.data(), tok.data() + tok.size(), out, std::chars_format::general);
    return r.ec == std::errc{} && r.ptr == tok.data() + tok.size() && std::isfinite(out);
}

/// Whether `tok` is wholly an integer ([+|-]digits) of magnitude below 2^31 (what tinyobjloader's int
/// holds); its value in `out`. Judged on the text: "4294967299" is an error, not 3.
inline bool whole_index(std::string_view tok, std::int64_t& out) {
    bool neg = false;
    if (!tok.empty() && (tok.front() == '+' || tok.front() == '-')) { neg = tok.front() == '-'; tok.remove_prefix(1); }
    if (tok.empty() || tok.size() > 10) return false;   // 10 digits cover 2^31 - 1; more overflow (or are padding)
    std::int64_t v = 0;
    for (char c : tok) {
        if (c < '0' || c > '9') return false;
        v = v * 10 + (c - '0');
    }
    if (v > std::numeric_limits<std::int32_t>::max()) return false;
    out = neg ? -v : v;
    return true;
}

/// Checks the text tinyobjloader would misread: `v` lines whose coordinates are not wholly finite
/// numbers (it reads "1,5" as 1, "nan" as 0) or fewer than three, and `f` lines whose indices are
/// not wholly integers below 2^31 or are relative indices before the first vertex (it would wrap
/// them into valid-looking faces). Line numbers are the file's.
inline void check_lines(const Text& t, const std::string& file) {
    std::int64_t seen = 0;   // `v` lines so far (relative indices count back from here)
    for_each_line(t.bytes(), [&](std::size_t l, std::string_view text) {
        const std::string where = "line " + std::to_string(t.file_line(l));
        std::string_view rest;
        if (keyword(text, "v", rest)) {
            int tokens = 0;
            for_each_token(rest, [&](std::string_view tok) {
                ++tokens;
                double v = 0;
                if (!whole_number(tok, v)) {
                    const bool overflow = std::from_chars(tok.data() + (tok.front() == '+'), tok.data() + tok.size(), v).ec ==
                                          std::errc::result_out_of_range;
                    throw LoadError(file, where, "vertex coordinate '" + std::string(tok) + "' is not a finite number" +
                                                     (overflow ? " (out of range)" : "") + ": '" + std::string(text) + "'");
                }
            });
            if (tokens < 3) throw LoadError(file, where, "vertex has fewer than 3 coordinates");
            ++seen;
            return true;
        }
        if (!keyword(text, "f", rest)) return true;
        for_each_token(rest, [&](std::string_view tok) {
            // v, v/vt, v//vn or v/vt/vn: each part present must be an integer below 2^31.
            for (int part = 0; !tok.empty() || part == 0; ++part) {
                const std::size_t slash = tok.find('/');
                const std::string_view num = tok.substr(0, slash);
                tok = slash == std::string_view::npos ? std::string_view() : tok.substr(slash + 1);
                if (part > 2) throw LoadError(file, where, "face vertex has more than 3 '/'-separated parts: '" + std::string(text) + "'");
                if (num.empty() && part > 0) continue;
                std::int64_t idx = 0;
                if (!whole_index(num, idx))
                    throw LoadError(file, where, "face index '" + std::string(num) +
                                                     "' is out of range or not an integer (indices must be integers of magnitude below 2^31)");
                if (part == 0 && idx < 0 && -idx > seen)
                    throw LoadError(file, where, "face index out of range: relative index " + std::to_string(idx) + " refers before the first vertex (" +
                                                     std::to_string(seen) + " vertices so far)");
                if (slash == std::string_view::npos) break;
            }
        });
        return true;
    });
}

/// Line of the `n`-th `v` line (0-based), for errors found after parsing.
inline std::size_t nth_vertex_line(const Text& t, std::size_t n) {
    std::size_t found = 0, seen = 0;
    for_each_line(t.bytes(), [&](std::size_t line, std::string_view text) {
        std::string_view rest;
        if (keyword(text, "v", rest) && seen++ == n) { found = line; return false; }
        return true;
    });
    return t.file_line(found);
}

/// First `f` line with an index that resolves outside [0, vertex_count); 0 if none.
inline std::size_t bad_face_line(const Text& t, std::int64_t vertex_count) {
    std::size_t found = 0;
    std::int64_t seen = 0;
    for_each_line(t.bytes(), [&](std::size_t line, std::string_view text) {
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
    return t.file_line(found);
}

inline std::string where_line(std::size_t line) { return line ? "line " + std::to_string(line) : std::string(); }

} // namespace detail::obj

#if DYNBVH_HAS_TINYOBJLOADER

inline Mesh read_obj(std::span<const char> bytes, std::string file, std::string mtl_dir, std::string* warnings) {
    using namespace detail::obj;
    const Text text = normalise(bytes);
    check_lines(text, file);

    tinyobj::attrib_t attrib;
    std::vector<tinyobj::shape_t> shapes;
    std::vector<tinyobj::material_t> materials;
    std::string warn, err;
    SpanBuf buf(text.bytes());
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
    std::size_t face_count = 0;
    for (const auto& sh : shapes) face_count += sh.mesh.num_face_vertices.size();
    if (nv == 0 && face_count == 0)
        throw LoadError(file, "", "no vertices and no faces: empty, or not an OBJ file");
    if (nv > std::numeric_limits<std::uint32_t>::max()) throw LoadError(file, "", "more than 2^32-1 vertices");
    m.vertices.resize(nv);
    for (std::size_t i = 0; i < nv; ++i) {
        const Vec3f v{static_cast<float>(attrib.vertices[3 * i]), static_cast<float>(attrib.vertices[3 * i + 1]),
                      static_cast<float>(attrib.vertices[3 * i + 2])};
        if (!dynbvh::is_finite(v))
            throw LoadError(file, where_line(nth_vertex_line(text, i)), "vertex " + std::to_string(i + 1) + " is not finite (or overflows float)");
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
                    throw LoadError(file, where_line(bad_face_line(text, static_cast<std::int64_t>(nv))),
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
