// SPDX-License-Identifier: MIT
/// @file io/scene.hpp
/// What the loaders return (PLY/OBJ meshes and frame sequences, BART): per-frame triangles with
/// material ids, per-object transforms, an animated camera, and the materials and lights MTL and
/// BART describe. The study's procedural scenes (bench/scenes) implement the same Scene interface;
/// how a renderer reads a material is bench/render's business. The core builders never include this header.
#pragma once

#include <array>
#include <cmath>
#include <cstdint>
#include <memory>
#include <stdexcept>
#include <string>
#include <vector>

#include "../triangle.hpp"

namespace dynbvh::io {

/// Error raised by every loader: names the file, where (line or byte offset) and what is wrong.
class LoadError : public std::runtime_error {
public:
    /// The message is "file:where: what" ("file: what" when `where` is empty).
    LoadError(std::string file, std::string where, std::string what)
        : std::runtime_error(file + (where.empty() ? "" : ":" + where) + ": " + what),
          file_(std::move(file)), where_(std::move(where)) {}
    /// The file the error concerns.
    const std::string& file() const noexcept { return file_; }
    /// "line N" or "byte N" (may be empty when the problem is the whole file).
    const std::string& where() const noexcept { return where_; }
private:
    std::string file_, where_;
};

/// Surface description read from MTL and BART `f`/`fm`.
/// Colours are linear RGB in [0, 1].
struct Material {
    /// Name (MTL `newmtl`).
    std::string name;
    /// Ambient colour (MTL Ka).
    Vec3f ambient{0, 0, 0};
    /// Diffuse colour (MTL Kd).
    Vec3f diffuse{0.8f, 0.8f, 0.8f};
    Vec3f specular{0, 0, 0};      ///< specular colour (MTL Ks, BART ks)
    float shininess = 0;          ///< Phong exponent (MTL Ns, BART shine)
    float transmission = 0;       ///< fraction transmitted (MTL: 1 - d, or Tf for illum 6 and 7; BART T)
    float ior = 1;                ///< index of refraction (MTL Ni, BART ior)
    float opacity = 1;            ///< MTL d (1 - Tr)
    int illum = 2;                ///< MTL illumination model, kept for the user
};

/// Point light (BART `l`).
struct Light {
    /// Position, world space.
    Vec3f position{0, 0, 0};
    /// Colour, linear RGB.
    Vec3f color{1, 1, 1};
};

/// Pinhole camera. `fov_y_deg` is the full vertical field of view in degrees.
struct Camera {
    /// Eye position.
    Vec3f from{0, 0, 1};
    /// The point looked at.
    Vec3f at{0, 0, 0};
    /// Up direction (need not be orthogonal to the view direction).
    Vec3f up{0, 1, 0};
    /// Full vertical field of view in degrees.
    float fov_y_deg = 45;
};

/// A camera that frames `bounds`: it looks at the centre from the +y/+z diagonal
/// (direction (0, 1, 2) normalised, about 27 degrees above the xz plane), far enough that the
/// bounding sphere fits the 45-degree vertical field of view. Empty or non-finite bounds give
/// the default Camera.
inline Camera frame_bounds_camera(const AABBf& bounds) {
    Camera c;
    if (bounds.is_empty() || !is_finite(bounds.min) || !is_finite(bounds.max)) return c;
    const Vec3f centre = bounds.center();
    float radius = 0.5f * length(bounds.diagonal());
    if (!(radius > 0)) radius = 1;
    const float half_fov = 0.5f * c.fov_y_deg * 3.14159265358979f / 180.0f;
    const float distance = radius / std::sin(half_fov);
    c.at = centre;
    c.from = centre + normalize(Vec3f{0, 1, 2}) * distance;
    c.up = {0, 1, 0};
    return c;
}

/// A column-major 4x4 affine transform (last row 0 0 0 1).
struct Transform {
    /// The 16 entries, column-major: m[12], m[13], m[14] is the translation.
    std::array<float, 16> m{1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1};
    /// M p for a point (translation applied).
    Vec3f apply_point(const Vec3f& p) const noexcept {
        return {m[0] * p.x + m[4] * p.y + m[8] * p.z + m[12], m[1] * p.x + m[5] * p.y + m[9] * p.z + m[13],
                m[2] * p.x + m[6] * p.y + m[10] * p.z + m[14]};
    }
    /// M v for a direction (no translation).
    Vec3f apply_vector(const Vec3f& v) const noexcept {
        return {m[0] * v.x + m[4] * v.y + m[8] * v.z, m[1] * v.x + m[5] * v.y + m[9] * v.z, m[2] * v.x + m[6] * v.y + m[10] * v.z};
    }
    /// Composition: (a * b) applies b first, then a.
    friend Transform operator*(const Transform& a, const Transform& b) noexcept {
        Transform r;
        for (std::size_t c = 0; c < 4; ++c)
            for (std::size_t rr = 0; rr < 4; ++rr) {
                float s = 0;
                for (std::size_t k = 0; k < 4; ++k) s += a.m[k * 4 + rr] * b.m[c * 4 + k];
                r.m[c * 4 + rr] = s;
            }
        return r;
    }
};

/// ObjectInstance::rigid_body of an object not known to move with any other.
inline constexpr std::uint32_t no_rigid_body = 0xffffffffu;

/// One object of a frame: a contiguous run of the frame's triangles and the
/// world transform already applied to them (so a refit/rebuild choice can be per object).
struct ObjectInstance {
    /// Object name (for reports).
    std::string name;
    /// Index of its first triangle in Frame::triangles.
    std::uint32_t first_triangle = 0;
    /// Its number of triangles.
    std::uint32_t triangle_count = 0;
    /// The world transform already applied to its triangles.
    Transform transform;
    /// True when its triangles may move between frames.
    bool animated = false;
    /// Objects with the same id (other than no_rigid_body) move as one rigid body: every frame gives
    /// them the same transform, and their triangles through its inverse do not change (BART: the
    /// transform node of an object without vertex animation). A two-level scene can make them one
    /// object and one instance.
    std::uint32_t rigid_body = no_rigid_body;
};

/// Triangle mesh with optional per-face material ids (as read from one PLY/OBJ file).
struct Mesh {
    /// Vertex positions, all finite (the readers reject NaN and infinity).
    std::vector<Vec3f> vertices;
    /// Triangles as three indices into `vertices`, all in range.
    std::vector<std::array<std::uint32_t, 3>> faces;
    std::vector<std::uint32_t> face_material;   ///< empty, or one id per face into `materials`
    /// Materials that `face_material` indexes (OBJ's MTL; empty for PLY).
    std::vector<Material> materials;

    /// Flattened world-space triangles (one per face).
    std::vector<Trianglef> triangles() const {
        std::vector<Trianglef> t(faces.size());
        for (std::size_t i = 0; i < faces.size(); ++i)
            t[i] = {vertices[faces[i][0]], vertices[faces[i][1]], vertices[faces[i][2]]};
        return t;
    }
    /// Box of all vertices (referenced or not).
    AABBf bounds() const { AABBf b; for (const auto& v : vertices) b.extend(v); return b; }
};

/// How the triangles of a scene move from frame to frame (UNC benchmark classes).
enum class Motion { none, rigid, hierarchical, semi_hierarchical, incoherent };

/// The motion class's name: "none", "rigid", "hierarchical", "semi-hierarchical" or "incoherent".
inline const char* to_string(Motion m) noexcept {
    switch (m) {
        case Motion::none: return "none";
        case Motion::rigid: return "rigid";
        case Motion::hierarchical: return "hierarchical";
        case Motion::semi_hierarchical: return "semi-hierarchical";
        case Motion::incoherent: return "incoherent";
    }
    return "unknown";
}

/// One evaluated frame: world-space triangles, one material id per triangle
/// (empty means material 0 everywhere), the objects they belong to, and the camera.
struct Frame {
    /// World-space triangles (their count may change between frames when SceneInfo::topology_changes).
    std::vector<Trianglef> triangles;
    /// One material id per triangle into SceneInfo::materials, or empty (material 0 everywhere).
    std::vector<std::uint32_t> material;
    /// The objects, each a contiguous run of `triangles`.
    std::vector<ObjectInstance> objects;
    /// The camera at this frame's time.
    Camera camera;
    double time = 0;   ///< seconds since the animation's start
};

/// Static description of an animated scene.
struct SceneInfo {
    /// Scene name (from the file, pattern or directory).
    std::string name;
    /// How the triangles move (see Motion).
    Motion motion = Motion::none;
    bool topology_changes = false;   ///< triangle count or connectivity changes between frames
    /// Number of frames.
    std::size_t frames = 1;
    /// The materials Frame::material indexes.
    std::vector<Material> materials;
    /// Point lights (BART; empty for PLY and OBJ).
    std::vector<Light> lights;
};

/// An animated scene: a fixed number of frames, each evaluated on demand.
/// Implementations: frame sequences (io/frames.hpp), BART (io/bart.hpp); the study's procedural scenes (bench/scenes).
class Scene {
public:
    virtual ~Scene() = default;
    /// Static description: name, motion, frame count, materials, lights.
    virtual const SceneInfo& info() const = 0;
    /// Number of frames, info().frames.
    std::size_t frame_count() const { return info().frames; }
    /// Evaluates frame `i` (0 <= i < frame_count()) into `out`, reusing its capacity.
    /// Throws LoadError (file scenes) or std::out_of_range.
    virtual void frame(std::size_t i, Frame& out) = 0;
};

} // namespace dynbvh::io
