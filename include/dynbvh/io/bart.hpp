// SPDX-License-Identifier: MIT
/// @file io/bart.hpp
/// Loader for BART, the Benchmark for Animated Ray Tracing (Lext, Assarsson, Möller,
/// IEEE CG&A 21(2), 2001): `.aff` files (NFF 3.9 plus animation) become an io::Scene whose
/// frames are evaluated on demand.
///
///     auto scene = dynbvh::io::load_bart("kitchen/kitchen.aff");
///     dynbvh::io::Frame f;
///     scene->frame(0, f);                       // or scene->evaluate(3.5 /*s*/, f)
///
/// Grammar supported (one command per keyword, tokens separated by white space, `#` or `%`
/// starts a comment that runs to the end of the line, `{` and `}` are tokens on their own):
///   v  from x y z  at x y z  up x y z  angle deg  hither h  resolution w h   camera (any order)
///   l  x y z [r g b]              point light        la name x y z [r g b]  light moved by `k name`
///   b  r g b                      background         am r g b               global ambient light
///   f  r g b Kd Ks shine T ior    NFF material       fm ar ag ab dr dg db sr sg sb shine T ior
///   p  n  (x y z)*n               polygon, fan-triangulated (n >= 3)
///   pp n  (x y z nx ny nz)*n      polygon patch, fan-triangulated (normals checked, not kept)
///   tt  tex (x y z u v)*3         textured triangle  ttp tex (x y z nx ny nz u v)*3
///   tpa n (time (x y z nx ny nz)*3)*n   triangle animated by linear interpolation between keys
///   m  vertices n (x y z)*n  [normals n (x y z)*n]  [texturecoords n tex (u v)*n]
///      triangles n (v0 v1 v2 [n0 n1 n2] [t0 t1 t2])*n                 indexed triangle mesh
///   c  bx by bz r0  ax ay az r1   cone/cylinder (not triangles; BartOptions::tessellate_cones)
///   s  x y z r                    sphere (kept as an analytic primitive, not triangulated)
///   xs sx sy sz  rx ry rz deg  tx ty tz { ... }   static transform T*R*S of everything inside
///   x  name { ... }               transform animated by the keyframes `k name` (identity if none)
///   k  name { transl n (t x y z tension continuity bias)*n   rot n (t ax ay az deg tension continuity bias)*n
///             scale n (t x y z tension continuity bias)*n    visibility n (t 0|1)*n }
///   a  start end frames           animation time range (seconds) and frame count
///   i  detail file                include `file` (relative to the including file) if detail <= the level
///   d  level                      detail level for later includes (default BartOptions::detail_level)
/// Keyframe semantics follow the BART reference code: see io/bart_spline.hpp. `k camera` animates
/// the viewpoint: position = its translation, view direction = its rotation applied to -z, up =
/// rotation applied to +y. The transform of a node is parent * (T * R * S). Rotation axes are
/// normalised (a zero axis is the identity).
///
/// Materials (global state, as in the reference parser: not scoped by `{ }` or includes):
/// `fm` maps to Material ambient/diffuse/specular/shininess/transmission/ior, an ior of 0 (BART's
/// value for opaque surfaces) becoming 1; `f r g b Kd Ks ...` gives diffuse = ambient = Kd * rgb,
/// specular = Ks (white). Identical materials are shared; material 0 is the default one used
/// before any `f`/`fm`. Material names are "file:line" of their first definition.
///
/// Objects (Frame::objects): every `m` is one object; the loose primitives (p, pp, tt, ttp,
/// tessellated c) of one file under one transform form one object, its `tpa` triangles another.
/// Names are "file:line" or "file polygons" relative to the entry file, plus "[x name]" of the
/// nearest keyframed transform. Static objects come first in the frame, then animated ones.
///
/// Time: `evaluate(seconds)` takes seconds since the animation start (`a start ...`); frame i of
/// `a start end n` is at (end - start) * i / (n - 1) (BART's rule) unless BartOptions::fps is set.
///
/// Errors: every malformed input throws io::LoadError naming the file, the line and the problem;
/// counts are checked against the bytes left in the file before anything is allocated.
#pragma once

#include <algorithm>
#include <array>
#include <atomic>
#include <charconv>
#include <cmath>
#include <cstdint>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <functional>
#include <limits>
#include <map>
#include <memory>
#include <optional>
#include <stdexcept>
#include <string>
#include <string_view>
#include <system_error>
#include <unordered_map>
#include <utility>
#include <vector>

#include "../executor.hpp"
#include "bart_spline.hpp"
#include "scene.hpp"

namespace dynbvh::io {

/// Knobs of the BART loader. Defaults reproduce the benchmark.
struct BartOptions {
    /// Frame rate of `frame(i)`. 0 (default): the file's own frame count from `a start end frames`,
    /// frame i at start + i * (end - start) / (frames - 1) as BART specifies. > 0: frames every 1/fps s.
    double fps = 0;
    /// Turn `c` cones/cylinders into triangles (open, no caps). Off by default: the canonical
    /// BART triangle counts exclude cones.
    bool tessellate_cones = false;
    /// Segments around a tessellated cone (clamped to [3, 65536]); 2 triangles each (1 when a radius is 0).
    unsigned cone_segments = 16;
    /// Initial detail level: `i level file` is included only when level <= this (changed by `d`).
    long detail_level = 0;
    /// Limits against malicious or broken input (include bombs, cycles through links).
    std::size_t max_include_depth = 64;
    /// Most `i` includes in all (repeats counted); beyond, LoadError.
    std::size_t max_includes = 1'000'000;
    std::uint64_t max_bytes = std::uint64_t(1) << 30;    ///< total bytes parsed, includes repeated
    /// Most triangles in all; beyond, LoadError.
    std::uint64_t max_triangles = std::uint64_t(1) << 27;
};

/// Supplies the text of an included file by its resolved path (the including file's directory
/// joined with the name, lexically normalised, '/' separators), or nullopt when it does not exist.
using BartResolver = std::function<std::optional<std::string>(const std::string& path)>;

/// What a BART file held (repeated includes counted each time).
struct BartStats {
    std::size_t files = 0;               ///< files parsed: the entry plus every include
    std::size_t polygons = 0;            ///< `p` and `pp`
    std::size_t polygon_triangles = 0;   ///< their fan triangles
    std::size_t meshes = 0;              ///< `m`
    /// their triangles
    std::size_t mesh_triangles = 0;
    std::size_t textured_triangles = 0;  ///< `tt` and `ttp`
    std::size_t animated_triangles = 0;  ///< `tpa`
    /// `c`
    std::size_t cones = 0;
    std::size_t cone_triangles = 0;      ///< only with BartOptions::tessellate_cones
    /// `s`
    std::size_t spheres = 0;
    std::size_t static_transforms = 0;   ///< `xs`
    std::size_t animated_transforms = 0; ///< `x`
    std::size_t animations = 0;          ///< `k` blocks
};

/// A cone or cylinder (`c`) in the space of its transform node; see BartScene::node_transform.
struct BartCone {
    /// @{
    /// Centres of the base and the apex circle.
    Vec3f base{}, apex{};
    /// @}
    /// @{
    /// Radii at the base and at the apex.
    float base_radius = 0, apex_radius = 0;   ///< negative radii (inside visible) made positive
    /// @}
    /// @{
    /// Material (into SceneInfo::materials) and transform node (BartScene::node_transform).
    std::uint32_t material = 0, node = 0;
    /// @}
};
/// A sphere (`s`) in the space of its transform node.
struct BartSphere {
    /// Centre, in its transform node's space.
    Vec3f center{};
    /// Radius.
    float radius = 0;
    /// @{
    /// Material (into SceneInfo::materials) and transform node (BartScene::node_transform).
    std::uint32_t material = 0, node = 0;
    /// @}
};

namespace bart {
/// Row-major 3x4 affine matrix in double (composition of the transform hierarchy).
struct Affine {
    /// Rows m[0..3], m[4..7], m[8..11]: the linear part, and the translation in column 3.
    std::array<double, 12> m{1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1, 0};

    /// T * R * S: scale first, then rotate, then translate (BART's order).
    static Affine trs(const std::array<double, 3>& t, const Quaternion& r, const std::array<double, 3>& s) noexcept {
        const auto R = r.matrix();
        Affine a;
        for (std::size_t row = 0; row < 3; ++row) {
            for (std::size_t c = 0; c < 3; ++c) a.m[row * 4 + c] = R[row * 3 + c] * s[c];
            a.m[row * 4 + 3] = t[row];
        }
        return a;
    }
    /// Composition: (a * b).apply(p) == a.apply(b.apply(p)) up to rounding.
    friend Affine operator*(const Affine& a, const Affine& b) noexcept {
        Affine r;
        for (std::size_t row = 0; row < 3; ++row)
            for (std::size_t c = 0; c < 4; ++c) {
                double s = a.m[row * 4 + 0] * b.m[0 * 4 + c] + a.m[row * 4 + 1] * b.m[1 * 4 + c] + a.m[row * 4 + 2] * b.m[2 * 4 + c];
                if (c == 3) s += a.m[row * 4 + 3];
                r.m[row * 4 + c] = s;
            }
        return r;
    }
    /// The transformed point, rounded to float.
    Vec3f apply(const Vec3f& p) const noexcept {
        return {float(m[0] * p.x + m[1] * p.y + m[2] * p.z + m[3]), float(m[4] * p.x + m[5] * p.y + m[6] * p.z + m[7]),
                float(m[8] * p.x + m[9] * p.y + m[10] * p.z + m[11])};
    }
    /// The same transform as a column-major io::Transform.
    Transform to_transform() const noexcept {
        Transform t;
        for (std::size_t row = 0; row < 3; ++row)
            for (std::size_t c = 0; c < 4; ++c) t.m[c * 4 + row] = float(m[row * 4 + c]);
        t.m[3] = t.m[7] = t.m[11] = 0;
        t.m[15] = 1;
        return t;
    }
};

/// The keyframe tracks of one `k name { ... }` block.
struct Animation {
    /// The name after `k`: the transform, light or camera it moves.
    std::string name;
    /// @{
    /// Translation and scale tracks (`transl`, `scale`), when present.
    std::optional<VectorSpline> translation, scale;
    /// @}
    /// Rotation track (`rot`), when present.
    std::optional<RotationSpline> rotation;
    std::vector<std::pair<double, bool>> visibility;   ///< (time, visible), times non-decreasing
    /// File of the `k` block (for messages).
    std::string file;
    /// Line of the `k` block in `file`.
    std::size_t line = 0;

    /// True when some track (translation, rotation, scale) is present.
    bool moves() const noexcept { return translation || rotation || scale; }
    /// T * R * S at time t (file clock); missing tracks are identity.
    Affine matrix(double t) const noexcept {
        const std::array<double, 3> T = translation ? (*translation)(t) : std::array<double, 3>{0, 0, 0};
        const std::array<double, 3> S = scale ? (*scale)(t) : std::array<double, 3>{1, 1, 1};
        const Quaternion R = rotation ? (*rotation)(t) : Quaternion{};
        return Affine::trs(T, R, S);
    }
    /// Visible before the first key; afterwards the flag of the last key at or before t.
    bool visible(double t) const noexcept {
        bool v = true;
        for (const auto& [kt, kv] : visibility) {
            if (t < kt) break;
            v = kv;
        }
        return v;
    }
};

class Parser;
} // namespace bart

/// A loaded BART scene. Triangles of objects that never move are flattened to world space
/// once at load and copied per frame; the triangles of animated objects (under a keyframed
/// transform, or `tpa`) follow them in the frame and are transformed per frame.
/// Objects invisible at a time (visibility keys) keep their slots, filled with NaN so that
/// builders skip them (make_references drops non-finite triangles).
class BartScene final : public Scene {
public:
    /// Name, frame count, materials and lights (see SceneInfo).
    const SceneInfo& info() const override { return info_; }

    /// Frame i at the frame rate of BartOptions::fps (default: BART's own `a` frame count).
    /// Throws std::out_of_range for i >= frame_count().
    void frame(std::size_t i, Frame& out) override { evaluate(frame_time(i), out); }

    /// Evaluates the scene `seconds` after the animation's start (any value; times outside the
    /// keyframes clamp as BART does). Copies the static triangles, transforms the animated ones.
    /// O(triangles) memory traffic, parallel over triangles with `ex`.
    template <class Exec = exec::default_executor>
    void evaluate(double seconds, Frame& out, const Exec& ex = {}) const;

    /// Like evaluate, but assumes `out` still holds an unmodified frame that this scene wrote
    /// (checked by sizes and object layout; otherwise it falls back to evaluate): only objects
    /// whose transform or visibility changed, and `tpa` triangles when the time changed, are
    /// recomputed; static triangles are not touched.
    template <class Exec = exec::default_executor>
    void update(double seconds, Frame& out, const Exec& ex = {}) const;

    /// Seconds since the start of frame i. Throws std::out_of_range for i >= frame_count().
    double frame_time(std::size_t i) const {
        if (i >= info_.frames)
            throw std::out_of_range("BartScene::frame: frame " + std::to_string(i) + " of " + std::to_string(info_.frames));
        return frame_step_ * double(i);
    }
    /// The animation's time range in the file's clock (`a start end frames`; 0, 0 when absent).
    double start_time() const noexcept { return start_; }
    /// End of that range.
    double end_time() const noexcept { return end_; }

    /// Triangles per frame (constant), of which the first static_triangle_count() never move.
    std::size_t triangle_count() const noexcept { return static_tris_.size() + anim_local_.size(); }
    /// Triangles that never move: the first ones of every frame.
    std::size_t static_triangle_count() const noexcept { return static_tris_.size(); }

    /// Camera `seconds` after the start (the `v` viewpoint, moved by `k camera` if present).
    Camera camera_at(double seconds) const noexcept;
    /// Lights `seconds` after the start (`la` lights moved by the translation of their `k`).
    std::vector<Light> lights_at(double seconds) const;
    /// World transform of a transform node (0 = the root) `seconds` after the start.
    Transform node_transform(std::uint32_t node, double seconds) const;

    /// Output resolution and near plane of the `v` viewpoint; background and global ambient colour.
    std::array<int, 2> resolution() const noexcept { return resolution_; }
    /// Near plane distance of the viewpoint.
    float hither() const noexcept { return hither_; }
    /// Background colour.
    Vec3f background() const noexcept { return background_; }
    /// Global ambient colour.
    Vec3f ambient() const noexcept { return ambient_; }
    /// Every `c` cone or cylinder, in its transform node's space.
    const std::vector<BartCone>& cones() const noexcept { return cones_; }
    /// Every `s` sphere, in its transform node's space.
    const std::vector<BartSphere>& spheres() const noexcept { return spheres_; }
    /// What the file held (see BartStats).
    const BartStats& stats() const noexcept { return stats_; }

private:
    friend class bart::Parser;
    struct Node {
        std::uint32_t parent = 0;
        std::int32_t anim = -1;          ///< animation driving this node (`x` with keys), -1 otherwise
        bool animated = false;           ///< it or an ancestor has an animation
        bart::Affine local;              ///< `xs` matrix (identity for `x` and the root)
        bart::Affine world;              ///< world matrix when !animated
    };
    struct AnimatedObject {
        std::uint32_t object = 0;        ///< index into objects_
        std::uint32_t node = 0;
        std::uint32_t first = 0;         ///< first triangle relative to the animated block
        std::uint32_t count = 0;
        bool tpa = false;                ///< vertex-animated (`tpa`): keys in tpa_*
    };
    struct NamedLight { Light light; std::int32_t anim = -1; };
    struct FrameXf { std::array<float, 12> m; bool visible; bool dirty; };

    void node_worlds(double file_time, std::vector<bart::Affine>& world, std::vector<char>& visible) const;
    template <class Exec> void transform_animated(double file_time, Frame& out, const std::vector<FrameXf>& xf, const Exec& ex) const;
    bool holds_our_frame(const Frame& out) const noexcept;

    SceneInfo info_;
    BartStats stats_;
    double start_ = 0, end_ = 0, frame_step_ = 0;
    std::vector<Node> nodes_;
    std::vector<bart::Animation> anims_;
    std::vector<ObjectInstance> objects_;          ///< frame layout: static objects, then animated ones
    std::vector<AnimatedObject> animated_;         ///< sorted by `first`
    std::vector<Trianglef> static_tris_;           ///< world space
    std::vector<Trianglef> anim_local_;            ///< object space, one per animated triangle
    std::vector<std::uint32_t> material_;          ///< per frame triangle
    std::vector<std::uint32_t> tpa_first_;         ///< per animated triangle: first key (size + 1 entries)
    std::vector<double> tpa_times_;
    std::vector<Trianglef> tpa_keys_;
    Camera camera_{};
    std::int32_t camera_anim_ = -1;
    std::array<int, 2> resolution_{0, 0};
    float hither_ = 0;
    Vec3f background_{0, 0, 0}, ambient_{1, 1, 1};
    std::vector<NamedLight> lights_;
    std::vector<BartCone> cones_;
    std::vector<BartSphere> spheres_;
};

/// Loads a BART scene from `aff_path`; includes are read relative to each including file.
/// Throws LoadError (file, line, problem) on any malformed or missing input.
std::unique_ptr<BartScene> load_bart(const std::string& aff_path, const BartOptions& options = {});

/// Parses a BART scene from memory (for tests and fuzzers): `name` is the entry file's path
/// used in messages and to resolve includes, which `resolver` supplies (none: includes fail).
std::unique_ptr<BartScene> load_bart_from_string(std::string_view text, const std::string& name = "memory.aff",
                                                 const BartResolver& resolver = {}, const BartOptions& options = {});

/// Convenience resolver over an in-memory file map {resolved path -> contents}.
inline BartResolver bart_file_map_resolver(std::map<std::string, std::string> files) {
    auto shared = std::make_shared<const std::map<std::string, std::string>>(std::move(files));
    return [shared](const std::string& path) -> std::optional<std::string> {
        auto it = shared->find(path);
        if (it == shared->end()) return std::nullopt;
        return it->second;
    };
}

// ------------------------------------------------------------------------------------------
// Implementation
// ------------------------------------------------------------------------------------------

namespace bart {

/// Reads a whole regular file; nullopt when it does not exist or cannot be read.
inline std::optional<std::string> read_file(const std::string& path) {
    std::error_code ec;
    if (!std::filesystem::is_regular_file(path, ec)) return std::nullopt;
    std::ifstream f(path, std::ios::binary);
    if (!f) return std::nullopt;
    f.seekg(0, std::ios::end);
    const std::streamoff size = f.tellg();
    if (size < 0) return std::nullopt;
    f.seekg(0, std::ios::beg);
    std::string s(static_cast<std::size_t>(size), '\0');
    if (size > 0 && !f.read(s.data(), size)) return std::nullopt;
    return s;
}

/// Whitespace-separated tokens with `#`/`%` comments; `{` and `}` are tokens of their own.
class Lexer {
public:
    /// Tokens of `text` (not copied: it must outlive the lexer).
    explicit Lexer(std::string_view text) noexcept : p_(text.data()), end_(text.data() + text.size()) {}

    /// Next token, empty at the end of the input (line() then stays at the last token's line).
    std::string_view next() noexcept {
        skip();
        if (p_ == end_) return {};
        tok_line_ = line_;
        const char* b = p_;
        if (p_ < end_ && (*p_ == '{' || *p_ == '}')) {
            ++p_;
        } else {
            while (p_ < end_ && !is_space(*p_) && *p_ != '{' && *p_ != '}' && *p_ != '#' && *p_ != '%') ++p_;
        }
        return {b, static_cast<std::size_t>(p_ - b)};
    }
    /// The next token without consuming it.
    std::string_view peek() noexcept {
        const char* p = p_;
        const std::size_t line = line_, tl = tok_line_;
        const std::string_view t = next();
        p_ = p;
        line_ = line;
        tok_line_ = tl;
        return t;
    }
    /// Line (1-based) of the last token returned by next().
    std::size_t line() const noexcept { return tok_line_; }
    /// Bytes not yet consumed.
    std::size_t remaining() const noexcept { return static_cast<std::size_t>(end_ - p_); }

private:
    static bool is_space(char c) noexcept { return c == ' ' || c == '\t' || c == '\n' || c == '\r' || c == '\f' || c == '\v'; }
    void skip() noexcept {
        while (p_ < end_) {
            const char c = *p_;
            if (c == '\n') { ++line_; ++p_; }
            else if (is_space(c)) ++p_;
            else if (c == '#' || c == '%') { while (p_ < end_ && *p_ != '\n') ++p_; }
            else break;
        }
    }
    const char* p_;
    const char* end_;
    std::size_t line_ = 1, tok_line_ = 1;
};

/// A token made printable and short for messages.
inline std::string show(std::string_view t) {
    std::string s;
    for (char c : t.substr(0, 40)) s += (static_cast<unsigned char>(c) >= 32 && static_cast<unsigned char>(c) < 127) ? c : '?';
    if (t.size() > 40) s += "...";
    return s;
}

/// Parses all of `t` as a double (std::from_chars, plus an optional leading '+'); false when it is not wholly one number.
inline bool parse_double(std::string_view t, double& v) noexcept {
    const char* b = t.data();
    const char* e = b + t.size();
    if (b < e && *b == '+') {
        ++b;
        if (b < e && (*b == '+' || *b == '-')) return false;
    }
    if (b == e) return false;
    const auto r = std::from_chars(b, e, v);
    return r.ec == std::errc() && r.ptr == e;
}

/// Builds a BartScene from AFF text (one instance per load).
class Parser {
public:
    /// A parser that fills `scene`; `entry` is the entry file's path (includes resolve against its directory).
    Parser(BartScene& scene, const BartOptions& options, const BartResolver& resolver, const std::string& entry)
        : s_(scene), opt_(options), resolver_(resolver), detail_(options.detail_level) {
        entry_dir_ = std::filesystem::path(entry).lexically_normal().parent_path().generic_string();
        s_.nodes_.push_back({});   // root
        s_.info_.materials.push_back(Material{.name = "default"});
    }

    /// Parses `text`, the contents of `entry`, and its includes into the scene; throws LoadError on bad input.
    void run(const std::string& entry, std::string_view text) {
        include_stack_.push_back(std::filesystem::path(entry).lexically_normal().generic_string());
        bytes_ = text.size();
        if (bytes_ > opt_.max_bytes) throw LoadError(entry, "", "file larger than BartOptions::max_bytes");
        parse_file(entry, text);
        finish(entry);
    }

private:
    struct Builder {
        std::string name;
        std::uint32_t node = 0;
        bool tpa = false;
        std::vector<Trianglef> tris;                 // object space (tpa: first key)
        std::vector<std::uint32_t> material;
        std::vector<std::uint32_t> key_count;        // tpa: keys per triangle
        std::vector<double> key_times;
        std::vector<Trianglef> keys;
    };
    struct FileCtx {
        std::string path;
        Lexer lex;
        std::string rel;
        std::unordered_map<std::uint32_t, std::uint32_t> loose, tpa;   // node -> builder
    };
    struct Open { std::uint32_t node; std::size_t line; };

    // ---- errors and tokens ------------------------------------------------------------------
    [[noreturn]] void fail(const std::string& what) const {
        throw LoadError(cur_->path, "line " + std::to_string(cur_->lex.line()), what);
    }
    Lexer& lex() noexcept { return cur_->lex; }
    std::string_view token(const char* what) {
        const std::string_view t = lex().next();
        if (t.empty()) fail(std::string("unexpected end of file, expected ") + what + " (truncated file?)");
        return t;
    }
    void expect(std::string_view word, const char* context) {
        const std::string_view t = lex().next();
        if (t.empty()) fail("unexpected end of file, expected '" + std::string(word) + "' " + context + " (truncated file?)");
        if (t != word) fail("expected '" + std::string(word) + "' " + context + ", got '" + show(t) + "'");
    }
    double number(const char* what) {
        const std::string_view t = token(what);
        double v = 0;
        if (!parse_double(t, v)) {
            double probe = 0;
            const auto r = std::from_chars(t.data(), t.data() + t.size(), probe);
            if (r.ec == std::errc::result_out_of_range) fail(std::string(what) + " '" + show(t) + "' is out of range");
            fail(std::string("expected ") + what + ", got '" + show(t) + "'");
        }
        if (!std::isfinite(v)) fail(std::string(what) + " is not a finite number: '" + show(t) + "'");
        return v;
    }
    float fnumber(const char* what) {
        const double v = number(what);
        if (std::abs(v) > double(std::numeric_limits<float>::max())) fail(std::string(what) + " is out of float range");
        return float(v);
    }
    Vec3f vec3(const char* what) {
        Vec3f v;
        v.x = fnumber(what);
        v.y = fnumber(what);
        v.z = fnumber(what);
        return v;
    }
    std::array<double, 3> dvec3(const char* what) { return {number(what), number(what), number(what)}; }
    long long integer(const char* what, long long lo, long long hi) {
        const std::string_view t = token(what);
        long long v = 0;
        const char* b = t.data();
        if (!t.empty() && *b == '+') ++b;
        const auto r = std::from_chars(b, t.data() + t.size(), v);
        if (r.ec != std::errc() || r.ptr != t.data() + t.size() || b == t.data() + t.size())
            fail(std::string("expected an integer ") + what + ", got '" + show(t) + "'");
        if (v < lo || v > hi) fail(std::string(what) + " " + std::to_string(v) + " is out of range [" + std::to_string(lo) + ", " + std::to_string(hi) + "]");
        return v;
    }
    /// A count of items of `tokens` tokens each, checked against the bytes left in the file.
    std::size_t count(const char* what, std::size_t tokens, std::size_t min = 0) {
        const std::string_view t = token(what);
        unsigned long long v = 0;
        const auto r = std::from_chars(t.data(), t.data() + t.size(), v);
        if (r.ec != std::errc() || r.ptr != t.data() + t.size()) fail(std::string("expected a count of ") + what + ", got '" + show(t) + "'");
        if (v < min) fail(std::string("count of ") + what + " is " + std::to_string(v) + ", needs at least " + std::to_string(min));
        // every token takes at least one character and one separator
        if (tokens > 0 && v > (lex().remaining() + 1) / (2 * tokens))
            fail(std::string("count of ") + what + " " + std::to_string(v) + " is more than the rest of the file can hold (wrong count or truncated file)");
        return static_cast<std::size_t>(v);
    }
    std::uint32_t index(std::size_t limit, const char* what, std::size_t item) {
        const std::string_view t = token(what);
        unsigned long long v = 0;
        const auto r = std::from_chars(t.data(), t.data() + t.size(), v);
        if (r.ec != std::errc() || r.ptr != t.data() + t.size())
            fail(std::string("triangle ") + std::to_string(item) + ": expected a " + what + ", got '" + show(t) + "'");
        if (v >= limit)
            fail(std::string("triangle ") + std::to_string(item) + ": " + what + " " + std::to_string(v) + " is out of range (there are " + std::to_string(limit) + ")");
        return static_cast<std::uint32_t>(v);
    }
    static bool looks_numeric(std::string_view t) noexcept {
        double v;
        return parse_double(t, v);
    }

    // ---- geometry sinks ---------------------------------------------------------------------
    std::uint32_t top() const noexcept { return open_.empty() ? 0u : open_.back().node; }
    std::string object_name(const std::string& what) const {
        std::string n = cur_->rel + what;
        if (const std::uint32_t k = named_[top()]; k != 0) n += " [" + node_names_[k] + "]";
        return n;
    }
    Builder& new_builder(std::string name, bool tpa) {
        Builder& b = builders_.emplace_back();
        b.name = std::move(name);
        b.node = top();
        b.tpa = tpa;
        return b;
    }
    Builder& loose() {
        auto [it, fresh] = cur_->loose.try_emplace(top(), std::uint32_t(builders_.size()));
        if (fresh) new_builder(object_name(" polygons"), false);
        return builders_[it->second];
    }
    void add_triangles(std::size_t n) {
        total_tris_ += n;
        if (total_tris_ > opt_.max_triangles)
            fail("more than BartOptions::max_triangles = " + std::to_string(opt_.max_triangles) + " triangles");
    }

    // ---- commands -----------------------------------------------------------------------------
    void parse_file(const std::string& path, std::string_view text) {
        FileCtx ctx{path, Lexer(text), rel_name(path), {}, {}};
        FileCtx* saved = cur_;
        cur_ = &ctx;
        ++s_.stats_.files;
        const std::size_t base = open_.size();
        for (;;) {
            const std::string_view t = lex().next();
            if (t.empty()) break;
            command(t, base);
        }
        if (open_.size() > base)
            throw LoadError(path, "line " + std::to_string(open_.back().line), "'{' is never closed (truncated file?)");
        cur_ = saved;
    }

    void command(std::string_view t, std::size_t base) {
        if (t == "m") return mesh();
        if (t == "p") return polygon(false);
        if (t == "pp") return polygon(true);
        if (t == "fm") return fill(true);
        if (t == "f") return fill(false);
        if (t == "xs") return static_xform();
        if (t == "x") return animated_xform();
        if (t == "}") {
            if (open_.size() <= base) fail("'}' without a matching '{'");
            open_.pop_back();
            return;
        }
        if (t == "i") return include();
        if (t == "k") return keyframes();
        if (t == "tpa") return animated_triangle();
        if (t == "tt") return textured_triangle(false);
        if (t == "ttp") return textured_triangle(true);
        if (t == "c") return cone();
        if (t == "s") return sphere();
        if (t == "l") return light(false);
        if (t == "la") return light(true);
        if (t == "v") return view();
        if (t == "a") return anim_params();
        if (t == "am") { const Vec3f a = vec3("ambient colour"); s_.ambient_ = a; return; }
        if (t == "b") { const Vec3f b = vec3("background colour"); s_.background_ = b; return; }
        if (t == "d") { detail_ = static_cast<long>(integer("detail level", std::numeric_limits<long>::min(), std::numeric_limits<long>::max())); return; }
        if (t == "{") fail("'{' without a transform before it");
        if (looks_numeric(t)) fail("unexpected number '" + show(t) + "' where a command was expected (a count too small earlier?)");
        fail("unknown command '" + show(t) + "'");
    }

    void view() {
        for (;;) {
            const std::string_view t = lex().peek();
            if (t == "from") { lex().next(); s_.camera_.from = vec3("camera 'from' coordinate"); }
            else if (t == "at") { lex().next(); s_.camera_.at = vec3("camera 'at' coordinate"); }
            else if (t == "up") { lex().next(); s_.camera_.up = vec3("camera 'up' coordinate"); }
            else if (t == "angle") {
                lex().next();
                const float a = fnumber("camera angle");
                if (!(a > 0 && a < 180)) fail("camera angle " + std::to_string(a) + " is not in (0, 180) degrees");
                s_.camera_.fov_y_deg = a;
            }
            else if (t == "hither") { lex().next(); s_.hither_ = fnumber("camera hither distance"); }
            else if (t == "resolution") {
                lex().next();
                s_.resolution_[0] = int(integer("x resolution", 0, 1 << 20));
                s_.resolution_[1] = int(integer("y resolution", 0, 1 << 20));
            }
            else break;
        }
    }

    void light(bool animated) {
        BartScene::NamedLight l;
        std::string name;
        if (animated) name = std::string(token("light name"));
        l.light.position = vec3("light position");
        if (looks_numeric(lex().peek())) l.light.color = vec3("light colour");
        if (animated) light_names_.emplace_back(s_.lights_.size(), name);
        s_.lights_.push_back(l);
    }

    void anim_params() {
        const double a = number("animation start time"), b = number("animation end time");
        const long long n = integer("frame count", 1, 100'000'000);
        if (b < a) fail("animation ends (" + std::to_string(b) + ") before it starts (" + std::to_string(a) + ")");
        s_.start_ = a;
        s_.end_ = b;
        frames_ = static_cast<std::size_t>(n);
    }

    void fill(bool extended) {
        Material m;
        if (extended) {
            m.ambient = vec3("ambient colour");
            m.diffuse = vec3("diffuse colour");
            m.specular = vec3("specular colour");
        } else {
            const Vec3f c = vec3("colour");
            const float kd = fnumber("Kd"), ks = fnumber("Ks");
            m.diffuse = c * kd;
            m.ambient = m.diffuse;
            m.specular = {ks, ks, ks};
        }
        m.shininess = fnumber("shine");
        m.transmission = fnumber("transmission");
        const float ior = fnumber("index of refraction");
        m.ior = ior > 0 ? ior : 1.0f;   // BART writes 0 for opaque materials
        m.name = cur_->rel + ":" + std::to_string(lex().line());
        const std::array<float, 12> key{m.ambient.x, m.ambient.y, m.ambient.z, m.diffuse.x, m.diffuse.y, m.diffuse.z,
                                        m.specular.x, m.specular.y, m.specular.z, m.shininess, m.transmission, m.ior};
        auto [it, fresh] = material_ids_.try_emplace(key, std::uint32_t(s_.info_.materials.size()));
        if (fresh) s_.info_.materials.push_back(std::move(m));
        material_ = it->second;
    }

    void polygon(bool patch) {
        const std::size_t n = count(patch ? "polygon patch vertices" : "polygon vertices", patch ? 6 : 3, 3);
        Builder& b = loose();
        Vec3f v0{}, prev{};
        for (std::size_t k = 0; k < n; ++k) {
            const Vec3f v = vec3("polygon vertex coordinate");
            if (patch) (void)vec3("polygon patch normal");
            if (k == 0) v0 = v;
            else if (k >= 2) { b.tris.push_back({v0, prev, v}); b.material.push_back(material_); }
            prev = v;
        }
        add_triangles(n - 2);
        ++s_.stats_.polygons;
        s_.stats_.polygon_triangles += n - 2;
    }

    void textured_triangle(bool patch) {
        (void)token("texture name");
        Builder& b = loose();
        Trianglef t;
        for (int k = 0; k < 3; ++k) {
            const Vec3f v = vec3("textured triangle vertex coordinate");
            if (patch) (void)vec3("textured triangle normal");
            (void)number("texture coordinate");
            (void)number("texture coordinate");
            (k == 0 ? t.p0 : k == 1 ? t.p1 : t.p2) = v;
        }
        b.tris.push_back(t);
        b.material.push_back(material_);
        add_triangles(1);
        ++s_.stats_.textured_triangles;
    }

    void animated_triangle() {
        const std::size_t n = count("animated triangle keys", 19, 1);
        auto [it, fresh] = cur_->tpa.try_emplace(top(), std::uint32_t(builders_.size()));
        if (fresh) new_builder(object_name(" animated triangles"), true);
        Builder& b = builders_[it->second];
        double last = -std::numeric_limits<double>::infinity();
        for (std::size_t k = 0; k < n; ++k) {
            const double t = number("animated triangle key time");
            if (t < last) fail("animated triangle key times must not decrease (" + std::to_string(t) + " after " + std::to_string(last) + ")");
            last = t;
            Trianglef tri;
            for (int v = 0; v < 3; ++v) {
                (v == 0 ? tri.p0 : v == 1 ? tri.p1 : tri.p2) = vec3("animated triangle vertex coordinate");
                (void)vec3("animated triangle normal");
            }
            b.key_times.push_back(t);
            b.keys.push_back(tri);
        }
        b.tris.push_back(b.keys[b.keys.size() - n]);
        b.material.push_back(material_);
        b.key_count.push_back(std::uint32_t(n));
        add_triangles(1);
        ++s_.stats_.animated_triangles;
    }

    void mesh() {
        const std::size_t line = lex().line();
        expect("vertices", "after 'm'");
        const std::size_t nv = count("mesh vertices", 3);
        std::vector<Vec3f> verts;
        verts.reserve(nv);
        for (std::size_t k = 0; k < nv; ++k) verts.push_back(vec3("mesh vertex coordinate"));
        std::size_t nn = 0, nt = 0;
        if (lex().peek() == "normals") {
            lex().next();
            nn = count("mesh normals", 3);
            for (std::size_t k = 0; k < nn; ++k) (void)vec3("mesh normal coordinate");
        }
        if (lex().peek() == "texturecoords") {
            lex().next();
            nt = count("mesh texture coordinates", 2);
            (void)token("texture name");
            for (std::size_t k = 0; k < nt; ++k) { (void)number("texture coordinate"); (void)number("texture coordinate"); }
        }
        expect("triangles", "in mesh (after vertices [normals] [texturecoords])");
        const bool has_t = nt > 0;
        const std::size_t per = 3u + (nn > 0 ? 3u : 0u) + (has_t ? 3u : 0u);
        const std::size_t ntri = count("mesh triangles", per);
        Builder& b = new_builder(object_name(":" + std::to_string(line)), false);
        b.tris.reserve(ntri);
        b.material.assign(ntri, material_);
        for (std::size_t k = 0; k < ntri; ++k) {
            const std::uint32_t a = index(nv, "vertex index", k), c1 = index(nv, "vertex index", k), c2 = index(nv, "vertex index", k);
            if (nn > 0) for (int j = 0; j < 3; ++j) (void)index(nn, "normal index", k);
            if (has_t) for (int j = 0; j < 3; ++j) (void)index(nt, "texture coordinate index", k);
            b.tris.push_back({verts[a], verts[c1], verts[c2]});
        }
        add_triangles(ntri);
        ++s_.stats_.meshes;
        s_.stats_.mesh_triangles += ntri;
    }

    void cone() {
        BartCone c;
        c.base = vec3("cone base coordinate");
        c.base_radius = fnumber("cone base radius");
        c.apex = vec3("cone apex coordinate");
        c.apex_radius = fnumber("cone apex radius");
        if (c.base == c.apex) fail("cone base and apex coincide");
        if (c.base_radius < 0) { c.base_radius = -c.base_radius; c.apex_radius = -c.apex_radius; }
        if (c.apex_radius < 0) fail("cone radii have different signs");
        c.material = material_;
        c.node = top();
        s_.cones_.push_back(c);
        ++s_.stats_.cones;
        if (opt_.tessellate_cones) tessellate(c);
    }

    void tessellate(const BartCone& c) {
        const unsigned n = std::clamp(opt_.cone_segments, 3u, 1u << 16);
        add_triangles(2 * std::size_t(n));   // checked before anything is allocated
        const Vec3f axis = normalize(c.apex - c.base);
        const Vec3f helper = std::abs(axis.x) < 0.9f ? Vec3f{1, 0, 0} : Vec3f{0, 1, 0};
        const Vec3f u = normalize(cross(axis, helper)), v = cross(axis, u);
        Builder& b = loose();
        std::size_t added = 0;
        const double two_pi = 6.283185307179586476925286766559;
        for (unsigned k = 0; k < n; ++k) {
            const double a0 = two_pi * k / n, a1 = two_pi * (k + 1) / n;
            const Vec3f d0 = u * float(std::cos(a0)) + v * float(std::sin(a0)), d1 = u * float(std::cos(a1)) + v * float(std::sin(a1));
            const Vec3f b0 = c.base + d0 * c.base_radius, b1 = c.base + d1 * c.base_radius;
            const Vec3f t0 = c.apex + d0 * c.apex_radius, t1 = c.apex + d1 * c.apex_radius;
            if (c.base_radius > 0) { b.tris.push_back({b0, b1, t1}); b.material.push_back(c.material); ++added; }
            if (c.apex_radius > 0) { b.tris.push_back({b0, t1, t0}); b.material.push_back(c.material); ++added; }
        }
        total_tris_ -= 2 * std::size_t(n) - added;
        s_.stats_.cone_triangles += added;
    }

    void sphere() {
        BartSphere s;
        s.center = vec3("sphere centre coordinate");
        s.radius = std::abs(fnumber("sphere radius"));
        s.material = material_;
        s.node = top();
        s_.spheres_.push_back(s);
        ++s_.stats_.spheres;
    }

    void open_node(BartScene::Node n, std::string name) {
        n.parent = top();
        if (s_.nodes_.size() >= std::numeric_limits<std::int32_t>::max()) fail("too many transforms");
        s_.nodes_.push_back(n);
        named_.push_back(name.empty() ? named_[n.parent] : std::uint32_t(s_.nodes_.size() - 1));
        node_names_.push_back(std::move(name));
        expect("{", "after the transform");
        open_.push_back({std::uint32_t(s_.nodes_.size() - 1), lex().line()});
    }

    void static_xform() {
        const std::array<double, 3> s = dvec3("static transform scale");
        const std::array<double, 3> axis = dvec3("static transform rotation axis");
        const double deg = number("static transform rotation angle");
        const std::array<double, 3> t = dvec3("static transform translation");
        BartScene::Node n;
        n.local = Affine::trs(t, Quaternion::from_axis_angle(axis, deg * (3.14159265358979323846 / 180.0)), s);
        ++s_.stats_.static_transforms;
        open_node(n, {});
    }

    void animated_xform() {
        const std::string name(token("transform name"));
        if (name == "{" || name == "}") fail("expected a transform name after 'x'");
        ++s_.stats_.animated_transforms;
        pending_.push_back({std::uint32_t(s_.nodes_.size()), name});
        open_node({}, name);
    }

    void keyframes() {
        Animation a;
        a.name = std::string(token("animation name"));
        if (a.name == "{" || a.name == "}") fail("expected an animation name after 'k'");
        a.file = cur_->path;
        a.line = lex().line();
        expect("{", "after the animation name");
        for (;;) {
            const std::string_view t = token("a keyframe track or '}'");
            if (t == "}") break;
            if (t == "transl" || t == "scale") {
                auto& track = t == "transl" ? a.translation : a.scale;
                if (track) fail("animation '" + a.name + "' has two " + std::string(t) + " tracks");
                const std::string what = std::string(t) + " keys";
                const std::size_t n = count(what.c_str(), 7, 4);
                std::vector<VectorKey> keys(n);
                for (std::size_t k = 0; k < n; ++k) {
                    keys[k].t = number("key time");
                    keys[k].value = dvec3("key value");
                    keys[k].tension = number("key tension");
                    keys[k].continuity = number("key continuity");
                    keys[k].bias = number("key bias");
                }
                track.emplace(keys);
            } else if (t == "rot") {
                if (a.rotation) fail("animation '" + a.name + "' has two rot tracks");
                const std::size_t n = count("rot keys", 8, 4);
                std::vector<RotationKey> keys(n);
                for (std::size_t k = 0; k < n; ++k) {
                    keys[k].t = number("key time");
                    keys[k].axis = dvec3("rotation axis");
                    keys[k].angle = number("rotation angle") * (3.14159265358979323846 / 180.0);
                    keys[k].tension = number("key tension");
                    keys[k].continuity = number("key continuity");
                    keys[k].bias = number("key bias");
                }
                a.rotation.emplace(keys);
            } else if (t == "visibility") {
                if (!a.visibility.empty()) fail("animation '" + a.name + "' has two visibility tracks");
                const std::size_t n = count("visibility keys", 2, 1);
                for (std::size_t k = 0; k < n; ++k) {
                    const double kt = number("key time");
                    const long long v = integer("visibility flag", 0, 1);
                    if (k > 0 && kt < a.visibility.back().first) fail("visibility key times must not decrease");
                    a.visibility.emplace_back(kt, v != 0);
                }
            } else {
                fail("unknown keyframe track '" + show(t) + "' (expected transl, rot, scale, visibility or '}')");
            }
        }
        ++s_.stats_.animations;
        // like the reference parser, the last definition of a name wins
        auto [it, fresh] = anim_ids_.try_emplace(a.name, std::int32_t(s_.anims_.size()));
        if (fresh) s_.anims_.push_back(std::move(a));
        else s_.anims_[std::size_t(it->second)] = std::move(a);
    }

    void include() {
        const long long level = integer("include detail level", std::numeric_limits<long long>::min(), std::numeric_limits<long long>::max());
        const std::string name(token("include file name"));
        if (level > detail_) return;
        const std::string from = cur_->path;
        const std::string path = (std::filesystem::path(from).parent_path() / name).lexically_normal().generic_string();
        for (std::size_t k = 0; k < include_stack_.size(); ++k)
            if (include_stack_[k] == path) {
                std::string chain;
                for (std::size_t j = k; j < include_stack_.size(); ++j) chain += include_stack_[j] + " -> ";
                fail("cyclic include: " + chain + path);
            }
        if (include_stack_.size() >= opt_.max_include_depth)
            fail("includes nested deeper than BartOptions::max_include_depth = " + std::to_string(opt_.max_include_depth));
        if (++includes_ > opt_.max_includes) fail("more than BartOptions::max_includes = " + std::to_string(opt_.max_includes) + " includes");
        auto it = cache_.find(path);
        if (it == cache_.end()) {
            std::optional<std::string> text = resolver_ ? resolver_(path) : std::nullopt;
            if (!text) fail("cannot open include file '" + show(name) + "' (looked for '" + path + "')");
            it = cache_.emplace(path, std::make_shared<const std::string>(std::move(*text))).first;
        }
        const std::shared_ptr<const std::string> text = it->second;
        bytes_ += text->size();
        if (bytes_ > opt_.max_bytes) fail("includes expand to more than BartOptions::max_bytes = " + std::to_string(opt_.max_bytes) + " bytes");
        include_stack_.push_back(path);
        parse_file(path, *text);
        include_stack_.pop_back();
    }

    std::string rel_name(const std::string& given) const {
        const std::string path = std::filesystem::path(given).lexically_normal().generic_string();
        if (!entry_dir_.empty() && path.size() > entry_dir_.size() + 1 && path.compare(0, entry_dir_.size(), entry_dir_) == 0 &&
            path[entry_dir_.size()] == '/')
            return path.substr(entry_dir_.size() + 1);
        return path;
    }

    // ---- after parsing: bind animations, flatten static geometry, lay out the frame ----------
    void finish(const std::string& entry);

    BartScene& s_;
    const BartOptions& opt_;
    const BartResolver& resolver_;
    long detail_;
    std::string entry_dir_;
    FileCtx* cur_ = nullptr;
    std::vector<Open> open_;
    std::vector<std::string> node_names_{std::string()};
    std::vector<std::uint32_t> named_{0};                                 // nearest `x` ancestor (0: none)
    std::vector<std::pair<std::uint32_t, std::string>> pending_;          // `x` nodes to bind
    std::vector<std::pair<std::size_t, std::string>> light_names_;        // `la` lights to bind
    std::vector<Builder> builders_;
    std::map<std::array<float, 12>, std::uint32_t> material_ids_;
    std::unordered_map<std::string, std::int32_t> anim_ids_;
    std::map<std::string, std::shared_ptr<const std::string>> cache_;
    std::vector<std::string> include_stack_;
    std::uint32_t material_ = 0;
    std::size_t frames_ = 1, includes_ = 0;
    std::uint64_t bytes_ = 0, total_tris_ = 0;
};

inline void Parser::finish(const std::string& entry) {
    // bind `x name` to `k name`; an `x` without keys stays the identity
    for (const auto& [node, name] : pending_) {
        auto it = anim_ids_.find(name);
        if (it != anim_ids_.end()) {
            const Animation& a = s_.anims_[std::size_t(it->second)];
            if (a.moves() || !a.visibility.empty()) s_.nodes_[node].anim = it->second;
        }
    }
    for (const auto& [light, name] : light_names_) {
        auto it = anim_ids_.find(name);
        if (it != anim_ids_.end() && s_.anims_[std::size_t(it->second)].translation) s_.lights_[light].anim = it->second;
    }
    if (auto it = anim_ids_.find("camera"); it != anim_ids_.end()) {
        const Animation& a = s_.anims_[std::size_t(it->second)];
        if (a.translation || a.rotation) s_.camera_anim_ = it->second;
    }
    bool nested_motion = false;
    for (std::size_t i = 1; i < s_.nodes_.size(); ++i) {
        BartScene::Node& n = s_.nodes_[i];
        const BartScene::Node& p = s_.nodes_[n.parent];
        if (n.anim >= 0 && p.animated) nested_motion = true;
        n.animated = n.anim >= 0 || p.animated;
        if (!n.animated) n.world = p.world * n.local;
    }

    // frame layout: static objects first (flattened now), then animated ones
    std::size_t n_static = 0, n_anim = 0;
    bool any_tpa = false, any_rigid = false;
    for (const Builder& b : builders_) {
        if (b.tris.empty()) continue;
        if (b.tpa || s_.nodes_[b.node].animated) n_anim += b.tris.size();
        else n_static += b.tris.size();
    }
    s_.static_tris_.reserve(n_static);
    s_.anim_local_.reserve(n_anim);
    s_.material_.reserve(n_static + n_anim);
    std::vector<std::uint32_t> anim_materials;
    anim_materials.reserve(n_anim);
    std::vector<ObjectInstance> anim_objects;
    s_.tpa_first_.reserve(n_anim + 1);
    for (Builder& b : builders_) {
        if (b.tris.empty()) continue;
        const BartScene::Node& node = s_.nodes_[b.node];
        ObjectInstance o;
        o.name = std::move(b.name);
        o.triangle_count = std::uint32_t(b.tris.size());
        if (!b.tpa) o.rigid_body = b.node;   // (vertex-animated objects change shape: no rigid body)
        if (!b.tpa && !node.animated) {
            o.first_triangle = std::uint32_t(s_.static_tris_.size());
            o.transform = node.world.to_transform();
            for (const Trianglef& t : b.tris) s_.static_tris_.push_back({node.world.apply(t.p0), node.world.apply(t.p1), node.world.apply(t.p2)});
            s_.material_.insert(s_.material_.end(), b.material.begin(), b.material.end());
            s_.objects_.push_back(std::move(o));
            continue;
        }
        o.animated = true;
        BartScene::AnimatedObject ao;
        ao.node = b.node;
        ao.first = std::uint32_t(s_.anim_local_.size());
        ao.count = o.triangle_count;
        ao.tpa = b.tpa;
        // tpa_first_[slot] = keys before this slot; rigid slots own no keys
        if (b.tpa) {
            any_tpa = true;
            std::size_t key = 0;
            for (std::size_t k = 0; k < b.tris.size(); ++k) {
                s_.tpa_first_.push_back(std::uint32_t(s_.tpa_times_.size()));
                for (std::uint32_t j = 0; j < b.key_count[k]; ++j, ++key) {
                    s_.tpa_times_.push_back(b.key_times[key]);
                    s_.tpa_keys_.push_back(b.keys[key]);
                }
            }
        } else {
            any_rigid = true;
            s_.tpa_first_.insert(s_.tpa_first_.end(), b.tris.size(), std::uint32_t(s_.tpa_times_.size()));
        }
        s_.anim_local_.insert(s_.anim_local_.end(), b.tris.begin(), b.tris.end());
        anim_materials.insert(anim_materials.end(), b.material.begin(), b.material.end());
        s_.animated_.push_back(ao);
        anim_objects.push_back(std::move(o));
    }
    s_.tpa_first_.push_back(std::uint32_t(s_.tpa_times_.size()));
    const std::uint32_t static_end = std::uint32_t(s_.static_tris_.size());
    for (std::size_t k = 0; k < anim_objects.size(); ++k) {
        anim_objects[k].first_triangle = static_end + s_.animated_[k].first;
        s_.animated_[k].object = std::uint32_t(s_.objects_.size());
        s_.objects_.push_back(std::move(anim_objects[k]));
    }
    s_.material_.insert(s_.material_.end(), anim_materials.begin(), anim_materials.end());

    // scene description
    SceneInfo& info = s_.info_;
    info.name = std::filesystem::path(entry).stem().string();
    info.motion = any_tpa ? Motion::incoherent : any_rigid ? (nested_motion ? Motion::hierarchical : Motion::rigid) : Motion::none;
    info.topology_changes = false;
    info.frames = frames_;
    s_.frame_step_ = frames_ > 1 ? (s_.end_ - s_.start_) / double(frames_ - 1) : 0.0;
    if (opt_.fps > 0) {
        if (!std::isfinite(opt_.fps)) throw LoadError(entry, "", "BartOptions::fps is not finite");
        const double n = std::floor((s_.end_ - s_.start_) * opt_.fps + 1e-9) + 1;
        if (!(n <= 1e8)) throw LoadError(entry, "", "BartOptions::fps gives more than 1e8 frames");
        info.frames = static_cast<std::size_t>(n);
        s_.frame_step_ = 1.0 / opt_.fps;
    }
    info.lights = s_.lights_at(0);
}

} // namespace bart

// ---- BartScene ---------------------------------------------------------------------------------

inline void BartScene::node_worlds(double t, std::vector<bart::Affine>& world, std::vector<char>& visible) const {
    world.resize(nodes_.size());
    visible.assign(nodes_.size(), 1);
    for (std::size_t i = 0; i < nodes_.size(); ++i) {
        const Node& n = nodes_[i];
        if (!n.animated) { world[i] = n.world; continue; }
        const bart::Affine local = n.anim >= 0 ? anims_[std::size_t(n.anim)].matrix(t) : n.local;
        world[i] = world[n.parent] * local;
        visible[i] = char(visible[n.parent] && (n.anim < 0 || anims_[std::size_t(n.anim)].visible(t)));
    }
}

inline Transform BartScene::node_transform(std::uint32_t node, double seconds) const {
    if (node >= nodes_.size()) throw std::out_of_range("BartScene::node_transform: no node " + std::to_string(node));
    std::vector<bart::Affine> world;
    std::vector<char> visible;
    node_worlds(start_ + seconds, world, visible);
    return world[node].to_transform();
}

inline Camera BartScene::camera_at(double seconds) const noexcept {
    Camera c = camera_;
    if (camera_anim_ < 0) return c;
    const double t = start_ + seconds;
    const bart::Animation& a = anims_[std::size_t(camera_anim_)];
    if (a.translation) {
        const auto p = (*a.translation)(t);
        const Vec3f from{float(p[0]), float(p[1]), float(p[2])};
        c.at = c.at - c.from + from;   // keep the view direction unless rotated below
        c.from = from;
    }
    if (a.rotation) {
        const auto R = (*a.rotation)(t).matrix();
        // the viewer looks along -z with +y up, rotated
        const Vec3f dir{float(-R[2]), float(-R[5]), float(-R[8])};
        c.at = c.from + dir;
        c.up = {float(R[1]), float(R[4]), float(R[7])};
    }
    return c;
}

inline std::vector<Light> BartScene::lights_at(double seconds) const {
    std::vector<Light> out;
    out.reserve(lights_.size());
    for (const NamedLight& l : lights_) {
        Light x = l.light;
        if (l.anim >= 0) {
            const auto p = (*anims_[std::size_t(l.anim)].translation)(start_ + seconds);
            x.position = {float(p[0]), float(p[1]), float(p[2])};
        }
        out.push_back(x);
    }
    return out;
}

inline bool BartScene::holds_our_frame(const Frame& out) const noexcept {
    if (out.triangles.size() != triangle_count() || out.material.size() != material_.size() || out.objects.size() != objects_.size())
        return false;
    for (std::size_t i = 0; i < objects_.size(); ++i) {
        const ObjectInstance &a = out.objects[i], &b = objects_[i];
        if (a.first_triangle != b.first_triangle || a.triangle_count != b.triangle_count || a.animated != b.animated || a.name != b.name ||
            a.rigid_body != b.rigid_body)
            return false;
    }
    return true;
}

template <class Exec>
void BartScene::transform_animated(double t, Frame& out, const std::vector<FrameXf>& xf, const Exec& ex) const {
    const std::size_t n = anim_local_.size();
    Trianglef* dst = out.triangles.data() + static_tris_.size();
    ex.for_blocks(0, n, [&](std::size_t lo, std::size_t hi) {
        // the animated object holding triangle lo
        std::size_t obj = std::size_t(std::upper_bound(animated_.begin(), animated_.end(), lo,
                                                       [](std::size_t v, const AnimatedObject& o) { return v < o.first; }) -
                                      animated_.begin()) - 1;
        for (std::size_t i = lo; i < hi;) {
            const AnimatedObject& o = animated_[obj];
            const std::size_t end = std::min<std::size_t>(hi, std::size_t(o.first) + o.count);
            const FrameXf& x = xf[obj];
            if (!x.dirty) { i = end; ++obj; continue; }
            if (!x.visible) {
                const float nan = std::numeric_limits<float>::quiet_NaN();
                for (; i < end; ++i) dst[i] = {{nan, nan, nan}, {nan, nan, nan}, {nan, nan, nan}};
                ++obj;
                continue;
            }
            const std::array<float, 12> m = x.m;   // a local copy: stores to dst cannot alias it
            const auto apply = [&m](const Vec3f& p) {
                return Vec3f{m[0] * p.x + m[1] * p.y + m[2] * p.z + m[3], m[4] * p.x + m[5] * p.y + m[6] * p.z + m[7],
                             m[8] * p.x + m[9] * p.y + m[10] * p.z + m[11]};
            };
            if (!o.tpa) {
                for (; i < end; ++i) {
                    const Trianglef& s = anim_local_[i];
                    dst[i] = {apply(s.p0), apply(s.p1), apply(s.p2)};
                }
            } else {
                for (; i < end; ++i) {
                    // linear interpolation between the keys around t, clamped at both ends
                    const std::size_t k0 = tpa_first_[i], k1 = tpa_first_[i + 1];
                    const double* times = tpa_times_.data();
                    std::size_t k = std::size_t(std::upper_bound(times + k0, times + k1, t) - times);
                    Trianglef s;
                    if (k == k0) s = tpa_keys_[k0];
                    else if (k == k1) s = tpa_keys_[k1 - 1];
                    else {
                        const double span = times[k] - times[k - 1];
                        const float w = span > 0 ? float((t - times[k - 1]) / span) : 1.0f;
                        const Trianglef &a = tpa_keys_[k - 1], &b = tpa_keys_[k];
                        s = {a.p0 + (b.p0 - a.p0) * w, a.p1 + (b.p1 - a.p1) * w, a.p2 + (b.p2 - a.p2) * w};
                    }
                    dst[i] = {apply(s.p0), apply(s.p1), apply(s.p2)};
                }
            }
            ++obj;
        }
    }, 4096);
}

template <class Exec>
void BartScene::evaluate(double seconds, Frame& out, const Exec& ex) const {
    const double t = start_ + seconds;
    out.time = seconds;
    out.camera = camera_at(seconds);
    out.triangles.resize(triangle_count());
    out.material.resize(material_.size());
    out.objects = objects_;
    const Trianglef* src = static_tris_.data();
    Trianglef* dst = out.triangles.data();
    const std::uint32_t* msrc = material_.data();
    std::uint32_t* mdst = out.material.data();
    ex.for_blocks(0, static_tris_.size(), [&](std::size_t lo, std::size_t hi) {
        std::memcpy(dst + lo, src + lo, (hi - lo) * sizeof(Trianglef));
    }, 1 << 16);
    ex.for_blocks(0, material_.size(), [&](std::size_t lo, std::size_t hi) {
        std::memcpy(mdst + lo, msrc + lo, (hi - lo) * sizeof(std::uint32_t));
    }, 1 << 16);
    if (animated_.empty()) return;
    std::vector<bart::Affine> world;
    std::vector<char> visible;
    node_worlds(t, world, visible);
    std::vector<FrameXf> xf(animated_.size());
    for (std::size_t k = 0; k < animated_.size(); ++k) {
        const AnimatedObject& o = animated_[k];
        const Transform tr = world[o.node].to_transform();
        out.objects[o.object].transform = tr;
        for (int r = 0; r < 3; ++r)
            for (int c = 0; c < 4; ++c) xf[k].m[std::size_t(r * 4 + c)] = tr.m[std::size_t(c * 4 + r)];
        xf[k].visible = visible[o.node] != 0;
        xf[k].dirty = true;
    }
    transform_animated(t, out, xf, ex);
}

template <class Exec>
void BartScene::update(double seconds, Frame& out, const Exec& ex) const {
    if (!holds_our_frame(out)) return evaluate(seconds, out, ex);
    const double t = start_ + seconds;
    const bool time_changed = !(out.time == seconds);
    out.time = seconds;
    out.camera = camera_at(seconds);
    if (animated_.empty()) return;
    std::vector<bart::Affine> world;
    std::vector<char> visible;
    node_worlds(t, world, visible);
    std::vector<FrameXf> xf(animated_.size());
    for (std::size_t k = 0; k < animated_.size(); ++k) {
        const AnimatedObject& o = animated_[k];
        const Transform tr = world[o.node].to_transform();
        ObjectInstance& inst = out.objects[o.object];
        const bool now_visible = visible[o.node] != 0;
        const bool was_visible = o.count == 0 || !std::isnan(out.triangles[inst.first_triangle].p0.x);
        xf[k].dirty = (o.tpa && time_changed) || tr.m != inst.transform.m || now_visible != was_visible;
        inst.transform = tr;
        for (int r = 0; r < 3; ++r)
            for (int c = 0; c < 4; ++c) xf[k].m[std::size_t(r * 4 + c)] = tr.m[std::size_t(c * 4 + r)];
        xf[k].visible = now_visible;
    }
    transform_animated(t, out, xf, ex);
}

// ---- entry points --------------------------------------------------------------------------------

inline std::unique_ptr<BartScene> load_bart_from_string(std::string_view text, const std::string& name,
                                                        const BartResolver& resolver, const BartOptions& options) {
    auto scene = std::make_unique<BartScene>();
    bart::Parser parser(*scene, options, resolver, name);
    parser.run(name, text);
    return scene;
}

inline std::unique_ptr<BartScene> load_bart(const std::string& aff_path, const BartOptions& options) {
    std::optional<std::string> text = bart::read_file(aff_path);
    if (!text) throw LoadError(aff_path, "", "cannot open file");
    const BartResolver resolver = [](const std::string& path) { return bart::read_file(path); };
    return load_bart_from_string(*text, aff_path, resolver, options);
}

} // namespace dynbvh::io
