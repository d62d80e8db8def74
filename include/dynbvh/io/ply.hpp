// SPDX-License-Identifier: MIT
/// @file io/ply.hpp
/// Stanford PLY reader and writer (Turk 1994 "The PLY polygon file format").
///
/// Reads ascii, binary_little_endian and binary_big_endian files; vertex positions of
/// any scalar type (float and double in practice) are stored as float. Every other
/// vertex or face property (colours, normals, confidence, ...) of any type, list
/// properties with any integer count type, and every other element (edge, material,
/// ...) are skipped. Faces are read from the `vertex_indices` (or `vertex_index`)
/// list of the `face` element and fan-triangulated: (v0, vk-1, vk) for k = 2..n-1.
/// Faces with fewer than 3 indices are skipped (PLY files use them for points and
/// lines); their indices are still range-checked. A file without a face element is a
/// point cloud (no faces).
///
/// Speed: the file is read with one read, the header is compiled into a per-property
/// layout (offsets, types), and each element is parsed by one loop specialised at
/// compile time for the file's endianness and the coordinate type, with straight
/// memcpy paths for packed float xyz and `list uchar int` triangles. ASCII uses
/// std::from_chars. No per-element allocation or virtual dispatch.
///
/// Bad input throws io::LoadError(file, "line N" or "byte N", problem): truncated
/// data, counts larger than the data, indices out of range, NaN or infinite
/// coordinates (also a finite double that overflows float), unknown format, type or
/// keyword, missing vertex element or x/y/z property, a face element without an index
/// list. Reservations are capped by what the remaining bytes can hold, so a header
/// that lies about its counts never causes a large allocation. ASCII records must be
/// one per line (blank lines are ignored); data after the last element is ignored.
/// Skipped ASCII properties are not validated. A leading UTF-8 byte-order mark is skipped.
///
/// A binary body longer than the header implies (e.g. doubles written under `property
/// float`) means the header does not describe the data: when no face survives it is an
/// error, otherwise a warning "<file>: byte N: ..." (one line) is appended to `*warnings`
/// when the caller passes it (a trailing line break alone is not warned about).
#pragma once

#include <algorithm>
#include <array>
#include <bit>
#include <cerrno>
#include <charconv>
#include <cstdint>
#include <cstdio>
#include <cstring>
#include <filesystem>
#include <limits>
#include <memory>
#include <span>
#include <stdexcept>
#include <string>
#include <string_view>
#include <system_error>
#include <type_traits>
#include <vector>

#include "scene.hpp"

namespace dynbvh::io {

/// How write_ply encodes the data section.
enum class PlyEncoding { ascii, binary_little_endian, binary_big_endian };

/// Parses a PLY file held in memory. `name_for_errors` is the file name reported in
/// LoadError. O(file size); never reads outside `bytes`.
/// Warnings (see above) are appended to `*warnings` when it is not null.
Mesh read_ply(std::span<const char> bytes, std::string name_for_errors, std::string* warnings = nullptr);

/// Reads the PLY file at `path` (one read of the whole file, then read_ply(bytes)).
Mesh read_ply(const std::string& path, std::string* warnings = nullptr);

/// Encodes `mesh` as PLY: float x y z, `list uchar int vertex_indices` faces (uint when
/// there are 2^31 vertices or more). ASCII floats use the shortest representation that
/// reads back bit-exact. Throws std::invalid_argument for indices out of range or
/// non-finite vertices (the reader would reject the file). Materials are not written.
std::string to_ply(const Mesh& mesh, PlyEncoding encoding = PlyEncoding::binary_little_endian);

/// Writes to_ply(mesh, encoding) to `path`, replacing it. Throws LoadError(path, ...) when
/// the file cannot be written.
void write_ply(const std::string& path, const Mesh& mesh, PlyEncoding encoding = PlyEncoding::binary_little_endian);

// ---------------------------------------------------------------------------------------
// Implementation
// ---------------------------------------------------------------------------------------

namespace detail {

/// A whole file in memory, read with one read (no zero-initialisation of the buffer).
struct FileBytes {
    std::unique_ptr<char[]> data;
    std::size_t size = 0;
    std::span<const char> span() const noexcept { return {data.get(), size}; }
};

/// Reads all of `path`; throws LoadError(path, "", why) when it cannot.
inline FileBytes read_file(const std::string& path) {
    namespace fs = std::filesystem;
    std::error_code ec;
    const auto status = fs::status(path, ec);
    if (ec || !fs::exists(status)) throw LoadError(path, "", "cannot open: no such file");
    if (fs::is_directory(status)) throw LoadError(path, "", "cannot open: is a directory");
    FileBytes out;
    std::FILE* f = std::fopen(path.c_str(), "rb");
    if (!f) throw LoadError(path, "", "cannot open: " + std::generic_category().message(errno));
    struct Closer { std::FILE* f; ~Closer() { std::fclose(f); } } closer{f};
    const auto size = fs::file_size(path, ec);
    if (ec) throw LoadError(path, "", "cannot read size: " + ec.message());
    out.size = static_cast<std::size_t>(size);
    out.data = std::make_unique_for_overwrite<char[]>(out.size == 0 ? 1 : out.size);
    if (out.size != 0 && std::fread(out.data.get(), 1, out.size, f) != out.size)
        throw LoadError(path, "", "read failed (file shorter than its size, or I/O error)");
    return out;
}

} // namespace detail

namespace detail::ply {

enum class Type : std::uint8_t { none, i8, u8, i16, u16, i32, u32, f32, f64 };

constexpr std::size_t size_of(Type t) noexcept {
    switch (t) {
        case Type::i8: case Type::u8: return 1;
        case Type::i16: case Type::u16: return 2;
        case Type::i32: case Type::u32: case Type::f32: return 4;
        case Type::f64: return 8;
        case Type::none: return 0;
    }
    return 0;
}
constexpr bool is_integer(Type t) noexcept { return t != Type::none && t != Type::f32 && t != Type::f64; }

inline Type parse_type(std::string_view s) noexcept {
    struct Name { std::string_view name; Type type; };
    static constexpr Name names[] = {
        {"char", Type::i8},    {"int8", Type::i8},     {"uchar", Type::u8},   {"uint8", Type::u8},
        {"short", Type::i16},  {"int16", Type::i16},   {"ushort", Type::u16}, {"uint16", Type::u16},
        {"int", Type::i32},    {"int32", Type::i32},   {"uint", Type::u32},   {"uint32", Type::u32},
        {"float", Type::f32},  {"float32", Type::f32}, {"double", Type::f64}, {"float64", Type::f64}};
    for (const auto& n : names)
        if (n.name == s) return n.type;
    return Type::none;
}

/// What the reader does with a property.
enum class Role : std::uint8_t { skip, x, y, z, indices };

struct Property {
    std::string name;
    Type type = Type::none;        ///< scalar type, or list item type
    Type count_type = Type::none;  ///< none: scalar; else the list's count type
    Role role = Role::skip;
    bool is_list() const noexcept { return count_type != Type::none; }
};

struct Element {
    std::string name;
    std::uint64_t count = 0;
    std::vector<Property> props;
    std::size_t line = 0;  ///< header line that declared it
    bool fixed_size() const noexcept {
        return std::none_of(props.begin(), props.end(), [](const Property& p) { return p.is_list(); });
    }
    std::size_t record_size() const noexcept {  // only meaningful when fixed_size()
        std::size_t s = 0;
        for (const auto& p : props) s += size_of(p.type);
        return s;
    }
    /// Smallest possible record: scalars plus the count field of each list.
    std::size_t min_binary_size() const noexcept {
        std::size_t s = 0;
        for (const auto& p : props) s += p.is_list() ? size_of(p.count_type) : size_of(p.type);
        return s;
    }
};

enum class Format : std::uint8_t { ascii, binary_le, binary_be };

struct Header {
    Format format = Format::ascii;
    std::vector<Element> elements;
    std::size_t data_offset = 0;  ///< first byte after end_header's newline
    std::size_t lines = 0;        ///< header lines, so ASCII data starts at line lines + 1
    int vertex = -1, face = -1;   ///< element indices
};

inline bool is_space(char c) noexcept { return c == ' ' || c == '\t' || c == '\r' || c == '\v' || c == '\f'; }

inline std::string quote(std::string_view s) {
    std::string out = "'";
    for (char c : s.substr(0, 40)) out += (static_cast<unsigned char>(c) < 32 || static_cast<unsigned char>(c) > 126) ? '?' : c;
    if (s.size() > 40) out += "...";
    return out + "'";
}

[[noreturn]] inline void fail_line(const std::string& file, std::size_t line, const std::string& what) {
    throw LoadError(file, "line " + std::to_string(line), what);
}
[[noreturn]] inline void fail_byte(const std::string& file, std::size_t byte, const std::string& what) {
    throw LoadError(file, "byte " + std::to_string(byte), what);
}

inline Header parse_header(std::span<const char> bytes, const std::string& file) {
    Header h;
    const char* const begin = bytes.data();
    const char* const end = begin + bytes.size();
    const char* p = begin;
    if (bytes.size() >= 3 && std::memcmp(begin, "\xEF\xBB\xBF", 3) == 0) p += 3;   // UTF-8 byte-order mark
    std::size_t line = 0;
    std::vector<std::string_view> tok;
    bool saw_format = false;
    for (;;) {
        if (p >= end) {
            if (line == 0) fail_line(file, 1, "empty file, not a PLY file");
            fail_line(file, line, "unexpected end of file in the header (no end_header)");
        }
        ++line;
        const char* eol = static_cast<const char*>(std::memchr(p, '\n', static_cast<std::size_t>(end - p)));
        const char* next = eol ? eol + 1 : end;
        if (!eol) eol = end;
        const std::string_view text(p, static_cast<std::size_t>(eol - p));
        p = next;
        tok.clear();
        for (std::size_t i = 0; i < text.size();) {
            while (i < text.size() && is_space(text[i])) ++i;
            const std::size_t s = i;
            while (i < text.size() && !is_space(text[i])) ++i;
            if (i > s) tok.push_back(text.substr(s, i - s));
        }
        if (line == 1) {
            if (tok.size() != 1 || tok[0] != "ply") fail_line(file, 1, "not a PLY file (first line must be 'ply')");
            continue;
        }
        if (tok.empty()) continue;
        const std::string_view key = tok[0];
        if (key == "comment" || key == "obj_info") continue;
        if (key == "format") {
            if (saw_format) fail_line(file, line, "duplicate format line");
            if (tok.size() != 3) fail_line(file, line, "format line must be 'format <ascii|binary_little_endian|binary_big_endian> 1.0'");
            if (tok[1] == "ascii") h.format = Format::ascii;
            else if (tok[1] == "binary_little_endian") h.format = Format::binary_le;
            else if (tok[1] == "binary_big_endian") h.format = Format::binary_be;
            else fail_line(file, line, "unknown format " + quote(tok[1]));
            if (tok[2] != "1.0" && tok[2] != "1") fail_line(file, line, "unsupported PLY version " + quote(tok[2]));
            saw_format = true;
        } else if (key == "element") {
            if (tok.size() != 3) fail_line(file, line, "element line must be 'element <name> <count>'");
            Element e;
            e.name = std::string(tok[1]);
            e.line = line;
            const auto r = std::from_chars(tok[2].data(), tok[2].data() + tok[2].size(), e.count);
            if (r.ec != std::errc{} || r.ptr != tok[2].data() + tok[2].size())
                fail_line(file, line, "bad count " + quote(tok[2]) + " for element " + quote(tok[1]));
            for (const auto& other : h.elements)
                if (other.name == e.name) fail_line(file, line, "duplicate element " + quote(tok[1]));
            if (e.name == "vertex") h.vertex = static_cast<int>(h.elements.size());
            if (e.name == "face") h.face = static_cast<int>(h.elements.size());
            h.elements.push_back(std::move(e));
        } else if (key == "property") {
            if (h.elements.empty()) fail_line(file, line, "property before any element");
            Property prop;
            if (tok.size() >= 2 && tok[1] == "list") {
                if (tok.size() != 5) fail_line(file, line, "list property must be 'property list <count type> <item type> <name>'");
                prop.count_type = parse_type(tok[2]);
                prop.type = parse_type(tok[3]);
                if (prop.count_type == Type::none) fail_line(file, line, "unknown type " + quote(tok[2]));
                if (prop.type == Type::none) fail_line(file, line, "unknown type " + quote(tok[3]));
                if (!is_integer(prop.count_type)) fail_line(file, line, "list count type " + quote(tok[2]) + " is not an integer type");
                prop.name = std::string(tok[4]);
            } else {
                if (tok.size() != 3) fail_line(file, line, "property must be 'property <type> <name>'");
                prop.type = parse_type(tok[1]);
                if (prop.type == Type::none) fail_line(file, line, "unknown type " + quote(tok[1]));
                prop.name = std::string(tok[2]);
            }
            Element& e = h.elements.back();
            const int ei = static_cast<int>(h.elements.size()) - 1;
            if (ei == h.vertex && !prop.is_list()) {
                if (prop.name == "x") prop.role = Role::x;
                if (prop.name == "y") prop.role = Role::y;
                if (prop.name == "z") prop.role = Role::z;
            }
            if (ei == h.face && prop.is_list() &&
                (prop.name == "vertex_indices" || prop.name == "vertex_index")) {
                if (!is_integer(prop.type)) fail_line(file, line, "face index type " + quote(tok[3]) + " is not an integer type");
                prop.role = Role::indices;
            }
            for (const auto& q : e.props)
                if (q.role != Role::skip && q.role == prop.role) fail_line(file, line, "duplicate property " + quote(prop.name));
            e.props.push_back(std::move(prop));
        } else if (key == "end_header") {
            if (tok.size() != 1) fail_line(file, line, "unexpected text after end_header");
            break;
        } else {
            fail_line(file, line, "unknown header keyword " + quote(key));
        }
    }
    h.data_offset = static_cast<std::size_t>(p - begin);
    h.lines = line;
    if (!saw_format) fail_line(file, 2, "missing format line");
    if (h.vertex < 0) fail_line(file, line, "no 'vertex' element");
    const Element& v = h.elements[static_cast<std::size_t>(h.vertex)];
    for (Role r : {Role::x, Role::y, Role::z})
        if (std::none_of(v.props.begin(), v.props.end(), [r](const Property& q) { return q.role == r; }))
            fail_line(file, v.line, std::string("element 'vertex' has no scalar '") + "xyz"[static_cast<int>(r) - 1] + "' property");
    if (v.count > std::numeric_limits<std::uint32_t>::max())
        fail_line(file, v.line, "vertex count " + std::to_string(v.count) + " exceeds 32-bit indices");
    if (h.face >= 0) {
        const Element& f = h.elements[static_cast<std::size_t>(h.face)];
        if (std::none_of(f.props.begin(), f.props.end(), [](const Property& q) { return q.role == Role::indices; }))
            fail_line(file, f.line, "element 'face' has no 'vertex_indices' list property");
    }
    return h;
}

// ----- binary -----------------------------------------------------------------------------

template <class U> constexpr U bswap(U v) noexcept {
    if constexpr (sizeof(U) == 1) return v;
    else if constexpr (sizeof(U) == 2) return static_cast<U>((v >> 8) | (v << 8));
    else if constexpr (sizeof(U) == 4)
        return static_cast<U>((v >> 24) | ((v >> 8) & 0xff00u) | ((v << 8) & 0xff0000u) | (v << 24));
    else {
        return static_cast<U>((static_cast<std::uint64_t>(bswap(static_cast<std::uint32_t>(v))) << 32) |
                              bswap(static_cast<std::uint32_t>(v >> 32)));
    }
}

template <std::size_t N> struct uint_of;
template <> struct uint_of<1> { using type = std::uint8_t; };
template <> struct uint_of<2> { using type = std::uint16_t; };
template <> struct uint_of<4> { using type = std::uint32_t; };
template <> struct uint_of<8> { using type = std::uint64_t; };

/// Loads a T stored at p (any alignment), byte-swapped when Swap.
template <class T, bool Swap> inline T load(const char* p) noexcept {
    using U = typename uint_of<sizeof(T)>::type;
    U u;
    std::memcpy(&u, p, sizeof u);
    if constexpr (Swap) u = bswap(u);
    return std::bit_cast<T>(u);
}

template <bool Swap> inline double load_real(Type t, const char* p) noexcept {
    switch (t) {
        case Type::i8: return load<std::int8_t, Swap>(p);
        case Type::u8: return load<std::uint8_t, Swap>(p);
        case Type::i16: return load<std::int16_t, Swap>(p);
        case Type::u16: return load<std::uint16_t, Swap>(p);
        case Type::i32: return load<std::int32_t, Swap>(p);
        case Type::u32: return load<std::uint32_t, Swap>(p);
        case Type::f32: return load<float, Swap>(p);
        case Type::f64: return load<double, Swap>(p);
        case Type::none: break;
    }
    return 0;
}
template <bool Swap> inline std::int64_t load_int(Type t, const char* p) noexcept {
    switch (t) {
        case Type::i8: return load<std::int8_t, Swap>(p);
        case Type::u8: return load<std::uint8_t, Swap>(p);
        case Type::i16: return load<std::int16_t, Swap>(p);
        case Type::u16: return load<std::uint16_t, Swap>(p);
        case Type::i32: return load<std::int32_t, Swap>(p);
        case Type::u32: return load<std::uint32_t, Swap>(p);
        default: break;
    }
    return -1;
}

inline bool finite_bits(float f) noexcept { return (std::bit_cast<std::uint32_t>(f) & 0x7f800000u) != 0x7f800000u; }

/// Index of the first vertex with a non-finite coordinate, or n.
inline std::size_t first_non_finite(const Vec3f* v, std::size_t n) noexcept {
    bool ok = true;
    for (std::size_t i = 0; i < n; ++i) {   // branch-free (&=, not &&), so the loop vectorises
        ok &= finite_bits(v[i].x);
        ok &= finite_bits(v[i].y);
        ok &= finite_bits(v[i].z);
    }
    if (ok) return n;
    for (std::size_t i = 0; i < n; ++i)
        if (!(finite_bits(v[i].x) && finite_bits(v[i].y) && finite_bits(v[i].z))) return i;
    return n;
}

/// Fixed-stride x/y/z of one type T.
template <class T, bool Swap>
void load_xyz(const char* base, std::size_t n, std::size_t stride, const std::array<std::size_t, 3>& off, Vec3f* out) noexcept {
    if constexpr (std::is_same_v<T, float>) {
        if (stride == 12 && off[0] == 0 && off[1] == 4 && off[2] == 8) {  // packed: one copy, then swap in place
            static_assert(sizeof(Vec3f) == 12);
            if (n != 0) std::memcpy(static_cast<void*>(out), base, n * 12);
            if constexpr (Swap)
                for (std::size_t i = 0; i < n; ++i) {
                    out[i].x = std::bit_cast<float>(bswap(std::bit_cast<std::uint32_t>(out[i].x)));
                    out[i].y = std::bit_cast<float>(bswap(std::bit_cast<std::uint32_t>(out[i].y)));
                    out[i].z = std::bit_cast<float>(bswap(std::bit_cast<std::uint32_t>(out[i].z)));
                }
            return;
        }
    }
    for (std::size_t i = 0; i < n; ++i) {
        const char* r = base + i * stride;
        out[i] = {static_cast<float>(load<T, Swap>(r + off[0])), static_cast<float>(load<T, Swap>(r + off[1])),
                  static_cast<float>(load<T, Swap>(r + off[2]))};
    }
}

/// Fixed-stride x/y/z of mixed types (rare): one switch per value.
template <bool Swap>
void load_xyz_mixed(const char* base, std::size_t n, std::size_t stride, const std::array<std::size_t, 3>& off,
                    const std::array<Type, 3>& type, Vec3f* out) noexcept {
    for (std::size_t i = 0; i < n; ++i) {
        const char* r = base + i * stride;
        out[i] = {static_cast<float>(load_real<Swap>(type[0], r + off[0])), static_cast<float>(load_real<Swap>(type[1], r + off[1])),
                  static_cast<float>(load_real<Swap>(type[2], r + off[2]))};
    }
}

/// `list uchar (u)int` triangles at a 13-byte stride. Stops (returns the face index) at the first
/// face that is not a triangle or has an index >= limit: the generic loop continues from there.
template <bool Swap>
std::size_t load_triangles_u8(const char* base, std::size_t n, std::uint32_t limit, std::array<std::uint32_t, 3>* out) noexcept {
    for (std::size_t i = 0; i < n; ++i) {
        const char* r = base + i * 13;
        if (static_cast<unsigned char>(r[0]) != 3) return i;
        const std::uint32_t a = load<std::uint32_t, Swap>(r + 1), b = load<std::uint32_t, Swap>(r + 5),
                            c = load<std::uint32_t, Swap>(r + 9);
        if ((a >= limit) | (b >= limit) | (c >= limit)) return i;
        out[i] = {a, b, c};
    }
    return n;
}

struct Context {
    std::span<const char> bytes;
    const std::string& file;
    const Header& h;
    std::uint32_t vertex_count = 0;
};

/// Appends the fan triangulation of one polygon, given its indices one at a time.
struct Fan {
    std::uint32_t first = 0, prev = 0;
    std::size_t k = 0;
    void add(std::uint32_t v, std::vector<std::array<std::uint32_t, 3>>& faces) {
        if (k == 0) first = v;
        else if (k >= 2) faces.push_back({first, prev, v});
        prev = v;
        ++k;
    }
};

/// Walks `count - first` records of a binary element one property at a time, with full
/// bounds checks. Appends x/y/z to m.vertices (vertex element) and fan-triangulates the index
/// list into m.faces (face element); everything else is skipped. Returns the end offset.
template <bool Swap>
std::size_t walk_binary(const Context& c, const Element& e, std::size_t pos, std::uint64_t first, Mesh& m) {
    const char* const data = c.bytes.data();
    const std::size_t size = c.bytes.size();
    const bool is_vertex = &e == &c.h.elements[static_cast<std::size_t>(c.h.vertex)];
    auto truncated = [&](std::uint64_t rec) {
        fail_byte(c.file, pos, "unexpected end of data in element '" + e.name + "' (record " + std::to_string(rec) + " of " +
                                   std::to_string(e.count) + ")");
    };
    for (std::uint64_t rec = first; rec < e.count; ++rec) {
        const std::size_t rec_pos = pos;
        Vec3f v{};
        for (const Property& p : e.props) {
            if (!p.is_list()) {
                const std::size_t s = size_of(p.type);
                if (size - pos < s) truncated(rec);
                if (p.role != Role::skip) v[static_cast<std::size_t>(p.role) - 1] = static_cast<float>(load_real<Swap>(p.type, data + pos));
                pos += s;
                continue;
            }
            const std::size_t cs = size_of(p.count_type), is = size_of(p.type);
            if (size - pos < cs) truncated(rec);
            const std::int64_t n = load_int<Swap>(p.count_type, data + pos);
            if (n < 0) fail_byte(c.file, pos, "negative list count " + std::to_string(n) + " in element '" + e.name + "'");
            pos += cs;
            if (static_cast<std::uint64_t>(n) > (size - pos) / is) truncated(rec);
            if (p.role == Role::indices) {
                Fan fan;
                for (std::int64_t k = 0; k < n; ++k, pos += is) {
                    const std::int64_t idx = load_int<Swap>(p.type, data + pos);
                    if (idx < 0 || idx >= c.vertex_count)
                        fail_byte(c.file, pos, "face " + std::to_string(rec) + " uses vertex " + std::to_string(idx) + " but there are " +
                                                   std::to_string(c.vertex_count) + " vertices");
                    if (n >= 3) fan.add(static_cast<std::uint32_t>(idx), m.faces);
                }
            } else {
                pos += static_cast<std::size_t>(n) * is;
            }
        }
        if (is_vertex) {
            if (!(finite_bits(v.x) && finite_bits(v.y) && finite_bits(v.z)))
                fail_byte(c.file, rec_pos, "vertex " + std::to_string(rec) + " has a non-finite coordinate");
            m.vertices.push_back(v);
        }
    }
    return pos;
}

/// Parses the binary body; returns the offset just past the last element.
template <bool Swap>
std::size_t parse_binary(const Context& c, Mesh& m) {
    std::size_t pos = c.h.data_offset;
    const std::size_t size = c.bytes.size();
    for (const Element& e : c.h.elements) {
        const bool is_vertex = &e == &c.h.elements[static_cast<std::size_t>(c.h.vertex)];
        const bool is_face = c.h.face >= 0 && &e == &c.h.elements[static_cast<std::size_t>(c.h.face)];
        if (e.fixed_size()) {
            const std::size_t rs = e.record_size();
            if (rs != 0 && e.count > (size - pos) / rs)
                fail_byte(c.file, pos, "truncated: element '" + e.name + "' declares " + std::to_string(e.count) + " records of " +
                                           std::to_string(rs) + " bytes but only " + std::to_string(size - pos) + " bytes remain");
            if (is_vertex) {
                const std::size_t n = static_cast<std::size_t>(e.count);
                std::array<std::size_t, 3> off{};
                std::array<Type, 3> type{};
                std::size_t o = 0;
                for (const Property& p : e.props) {
                    if (p.role != Role::skip) {
                        off[static_cast<std::size_t>(p.role) - 1] = o;
                        type[static_cast<std::size_t>(p.role) - 1] = p.type;
                    }
                    o += size_of(p.type);
                }
                m.vertices.resize(n);
                const char* base = c.bytes.data() + pos;
                if (type[0] == type[1] && type[1] == type[2] && type[0] == Type::f32)
                    load_xyz<float, Swap>(base, n, rs, off, m.vertices.data());
                else if (type[0] == type[1] && type[1] == type[2] && type[0] == Type::f64)
                    load_xyz<double, Swap>(base, n, rs, off, m.vertices.data());
                else
                    load_xyz_mixed<Swap>(base, n, rs, off, type, m.vertices.data());
                const std::size_t bad = first_non_finite(m.vertices.data(), n);
                if (bad != n) fail_byte(c.file, pos + bad * rs, "vertex " + std::to_string(bad) + " has a non-finite coordinate");
            }
            pos += static_cast<std::size_t>(e.count) * rs;
            continue;
        }
        if (is_vertex) {
            m.vertices.reserve(static_cast<std::size_t>(std::min<std::uint64_t>(e.count, (size - pos) / std::max<std::size_t>(1, e.min_binary_size()))));
            pos = walk_binary<Swap>(c, e, pos, 0, m);
            continue;
        }
        const std::size_t min_rs = std::max<std::size_t>(1, e.min_binary_size());
        if (!is_face) {  // skip an unknown element with lists, record by record
            pos = walk_binary<Swap>(c, e, pos, 0, m);
            continue;
        }
        std::uint64_t done = 0;
        const Property& ip = e.props.front();
        if (e.props.size() == 1 && ip.count_type == Type::u8 && (ip.type == Type::i32 || ip.type == Type::u32)) {
            const std::size_t n = static_cast<std::size_t>(std::min<std::uint64_t>(e.count, (size - pos) / 13));
            const std::uint32_t limit = ip.type == Type::i32 ? std::min<std::uint32_t>(c.vertex_count, 0x80000000u) : c.vertex_count;
            const std::size_t base = m.faces.size();
            m.faces.resize(base + n);
            done = load_triangles_u8<Swap>(c.bytes.data() + pos, n, limit, m.faces.data() + base);
            m.faces.resize(base + static_cast<std::size_t>(done));
            pos += static_cast<std::size_t>(done) * 13;
        }
        if (done < e.count) {
            m.faces.reserve(m.faces.size() + static_cast<std::size_t>(std::min<std::uint64_t>(e.count - done, (size - pos) / min_rs)));
            pos = walk_binary<Swap>(c, e, pos, done, m);
        }
    }
    return pos;
}

// ----- ascii ------------------------------------------------------------------------------

struct AsciiCursor {
    const char* p;
    const char* end;
    const char* eol = nullptr;  ///< end of the current record's line
    std::size_t line;           ///< number of the current line
    const std::string& file;

    /// Moves to the next non-blank line; false at end of data.
    bool next_record() {
        for (;;) {
            if (eol) {  // step past the previous record's line
                p = eol < end ? eol + 1 : end;
                ++line;
            }
            if (p >= end) { eol = end; return false; }
            eol = static_cast<const char*>(std::memchr(p, '\n', static_cast<std::size_t>(end - p)));
            if (!eol) eol = end;
            const char* q = p;
            while (q < eol && is_space(*q)) ++q;
            if (q < eol) { p = q; return true; }
        }
    }
    [[noreturn]] void fail(const std::string& what) const { fail_line(file, line, what); }
    std::string_view token_at(const char* q) const {
        const char* e = q;
        while (e < eol && !is_space(*e)) ++e;
        return {q, static_cast<std::size_t>(e - q)};
    }
    /// Skips blanks; fails when the line has no more values.
    void need_value(const char* what) {
        while (p < eol && is_space(*p)) ++p;
        if (p >= eol) fail(std::string("missing value: expected ") + what);
    }
    void skip_token(const char* what) {
        need_value(what);
        while (p < eol && !is_space(*p)) ++p;
    }
    template <class T> T real(const char* what) {
        need_value(what);
        const char* q = p;
        if (*q == '+') ++q;
        T v{};
        const auto r = std::from_chars(q, eol, v);
        if (r.ec == std::errc::result_out_of_range) fail(std::string(what) + " " + quote(token_at(p)) + " is not a finite number");
        if (r.ec != std::errc{} || (r.ptr < eol && !is_space(*r.ptr))) fail(std::string("bad ") + what + " " + quote(token_at(p)));
        p = r.ptr;
        return v;
    }
    std::int64_t integer(const char* what) {
        need_value(what);
        const char* q = p;
        if (*q == '+') ++q;
        std::int64_t v = 0;
        const auto r = std::from_chars(q, eol, v);
        if (r.ec != std::errc{} || (r.ptr < eol && !is_space(*r.ptr))) fail(std::string("bad ") + what + " " + quote(token_at(p)));
        p = r.ptr;
        return v;
    }
    void end_record(const Element& e) {
        while (p < eol && is_space(*p)) ++p;
        if (p < eol) fail("extra value " + quote(token_at(p)) + " at the end of a '" + e.name + "' record (one record per line)");
    }
};

inline void parse_ascii(const Context& c, Mesh& m) {
    AsciiCursor cur{c.bytes.data() + c.h.data_offset, c.bytes.data() + c.bytes.size(), nullptr, c.h.lines + 1, c.file};
    for (const Element& e : c.h.elements) {
        if (e.props.empty()) continue;  // records without values take no lines
        const bool is_vertex = &e == &c.h.elements[static_cast<std::size_t>(c.h.vertex)];
        const bool is_face = c.h.face >= 0 && &e == &c.h.elements[static_cast<std::size_t>(c.h.face)];
        // every record is at least one line of 2 bytes per value: caps what a lying count can reserve
        const std::size_t remaining = static_cast<std::size_t>(cur.end - cur.p);
        const std::size_t cap = static_cast<std::size_t>(std::min<std::uint64_t>(e.count, remaining / (2 * std::max<std::size_t>(1, e.props.size()))));
        if (is_vertex) m.vertices.reserve(cap);
        if (is_face) m.faces.reserve(m.faces.size() + cap);
        for (std::uint64_t rec = 0; rec < e.count; ++rec) {
            if (!cur.next_record())
                cur.fail("unexpected end of file in element '" + e.name + "' (record " + std::to_string(rec) + " of " + std::to_string(e.count) + ")");
            Vec3f v{};
            for (const Property& p : e.props) {
                if (!p.is_list()) {
                    if (p.role == Role::skip) cur.skip_token(p.name.c_str());
                    else {
                        float& dst = v[static_cast<std::size_t>(p.role) - 1];
                        if (p.type == Type::f32) dst = cur.real<float>(p.name.c_str());
                        else dst = static_cast<float>(cur.real<double>(p.name.c_str()));
                        if (!finite_bits(dst)) cur.fail("vertex " + std::to_string(rec) + " has a non-finite coordinate " + p.name);
                    }
                    continue;
                }
                const std::int64_t n = cur.integer("list count");
                if (n < 0) cur.fail("negative list count " + std::to_string(n));
                if (p.role != Role::indices) {
                    for (std::int64_t k = 0; k < n; ++k) cur.skip_token("list item");
                    continue;
                }
                Fan fan;
                for (std::int64_t k = 0; k < n; ++k) {
                    const std::int64_t idx = cur.integer("vertex index");
                    if (idx < 0 || idx >= c.vertex_count)
                        cur.fail("face " + std::to_string(rec) + " uses vertex " + std::to_string(idx) + " but there are " +
                                 std::to_string(c.vertex_count) + " vertices");
                    if (n >= 3) fan.add(static_cast<std::uint32_t>(idx), m.faces);
                }
            }
            cur.end_record(e);
            if (is_vertex) m.vertices.push_back(v);
        }
    }
}

} // namespace detail::ply

inline Mesh read_ply(std::span<const char> bytes, std::string name_for_errors, std::string* warnings) {
    using namespace detail::ply;
    const Header h = parse_header(bytes, name_for_errors);
    Mesh m;
    const Context c{bytes, name_for_errors, h, static_cast<std::uint32_t>(h.elements[static_cast<std::size_t>(h.vertex)].count)};
    constexpr bool little = std::endian::native == std::endian::little;
    static_assert(little || std::endian::native == std::endian::big, "mixed-endian hosts are not supported");
    std::size_t end = bytes.size();
    switch (h.format) {
        case Format::ascii: parse_ascii(c, m); break;
        case Format::binary_le: end = parse_binary<!little>(c, m); break;
        case Format::binary_be: end = parse_binary<little>(c, m); break;
    }
    // Bytes after the last element: the header's types or counts do not describe the body.
    std::size_t extra = bytes.size() - end;
    const std::string_view tail(bytes.data() + end, extra);
    if (tail == "\n" || tail == "\r\n") extra = 0;
    if (extra != 0) {
        const std::string what = std::to_string(extra) + " bytes after the last element: the header's types or counts do not "
                                 "match the body (e.g. doubles written under 'property float')";
        if (h.face >= 0 && m.faces.empty()) fail_byte(name_for_errors, end, what + ", and no face was read");
        if (warnings) *warnings += name_for_errors + ": byte " + std::to_string(end) + ": " + what + "\n";
    }
    return m;
}

inline Mesh read_ply(const std::string& path, std::string* warnings) {
    const auto file = detail::read_file(path);
    return read_ply(file.span(), path, warnings);
}

inline std::string to_ply(const Mesh& mesh, PlyEncoding encoding) {
    using namespace detail::ply;
    const std::size_t nv = mesh.vertices.size();
    if (nv > std::numeric_limits<std::uint32_t>::max()) throw std::invalid_argument("dynbvh::io::to_ply: more than 2^32-1 vertices");
    for (std::size_t i = 0; i < nv; ++i)
        if (!dynbvh::is_finite(mesh.vertices[i]))
            throw std::invalid_argument("dynbvh::io::to_ply: vertex " + std::to_string(i) + " is not finite");
    for (std::size_t f = 0; f < mesh.faces.size(); ++f)
        for (std::uint32_t v : mesh.faces[f])
            if (v >= nv)
                throw std::invalid_argument("dynbvh::io::to_ply: face " + std::to_string(f) + " uses vertex " + std::to_string(v) +
                                            " but there are " + std::to_string(nv));
    const bool big_index = nv > 0x7fffffffu;
    std::string out = "ply\nformat ";
    out += encoding == PlyEncoding::ascii ? "ascii" : encoding == PlyEncoding::binary_little_endian ? "binary_little_endian" : "binary_big_endian";
    out += " 1.0\ncomment written by dynbvh\nelement vertex " + std::to_string(nv) +
           "\nproperty float x\nproperty float y\nproperty float z\nelement face " + std::to_string(mesh.faces.size()) +
           (big_index ? "\nproperty list uchar uint vertex_indices\nend_header\n" : "\nproperty list uchar int vertex_indices\nend_header\n");
    const std::size_t header = out.size();
    if (encoding == PlyEncoding::ascii) {
        char buf[64];
        for (const Vec3f& v : mesh.vertices) {
            for (int k = 0; k < 3; ++k) {
                const auto r = std::to_chars(buf, buf + sizeof buf, v[static_cast<std::size_t>(k)]);
                out.append(buf, r.ptr);
                out += k == 2 ? '\n' : ' ';
            }
        }
        for (const auto& f : mesh.faces) {
            out += '3';
            for (std::uint32_t i : f) {
                out += ' ';
                const auto r = std::to_chars(buf, buf + sizeof buf, i);
                out.append(buf, r.ptr);
            }
            out += '\n';
        }
        return out;
    }
    const bool swap = (encoding == PlyEncoding::binary_big_endian) == (std::endian::native == std::endian::little);
    out.resize(header + nv * 12 + mesh.faces.size() * 13);
    char* p = out.data() + header;
    auto put32 = [&](std::uint32_t u) {
        if (swap) u = bswap(u);
        std::memcpy(p, &u, 4);
        p += 4;
    };
    for (const Vec3f& v : mesh.vertices) {
        put32(std::bit_cast<std::uint32_t>(v.x));
        put32(std::bit_cast<std::uint32_t>(v.y));
        put32(std::bit_cast<std::uint32_t>(v.z));
    }
    for (const auto& f : mesh.faces) {
        *p++ = 3;
        for (std::uint32_t i : f) put32(i);
    }
    return out;
}

inline void write_ply(const std::string& path, const Mesh& mesh, PlyEncoding encoding) {
    const std::string data = to_ply(mesh, encoding);
    std::FILE* f = std::fopen(path.c_str(), "wb");
    if (!f) throw LoadError(path, "", "cannot open for writing: " + std::generic_category().message(errno));
    const bool ok = std::fwrite(data.data(), 1, data.size(), f) == data.size();
    if (std::fclose(f) != 0 || !ok) throw LoadError(path, "", "write failed: " + std::generic_category().message(errno));
}

} // namespace dynbvh::io
