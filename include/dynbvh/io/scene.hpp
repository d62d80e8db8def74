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
    LoadError(std::string file, std::string where, std::string what)
        : std::runtime_error(file + (where.empty() ? "" : ":" + where) + ": " + what),
          file_(std::move(file)), where_(std::move(where)) {}
    const std::string& file() const noexcept { return file_; }
    /// "line N" or "byte N" (may be empty when the problem is the whole file).
    const std::string& where() const noexcept { return where_; }
private:
    std::string file_, where_;
};

/// Surface description read from MTL and BART `f`/`fm`.
/// Colours are linear RGB in [0, 1].
struct Material {
    std::string name;
    Vec3f ambient{0, 0, 0};
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
    Vec3f position{0, 0, 0};
    Vec3f color{1, 1, 1};
};

/// Pinhole camera. `fov_y_deg` is the full vertical field of view in degrees.
struct Camera {
    Vec3f from{0, 0, 1};
    Vec3f at{0, 0, 0};
    Vec3f up{0, 1, 0};
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
    std::array<float, 16> m{1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1};
    Vec3f apply_point(const Vec3f& p) const noexcept {
        return {m[0] * p.x + m[4] * p.y + m[8] * p.z + m[12], m[1] * p.x + m[5] * p.y + m[9] * p.z + m[13],
                m[2] * p.x + m[6] * p.y + m[10] * p.z + m[14]};
    }
    Vec3f apply_vector(const Vec3f& v) const noexcept {
        return {m[0] * v.x + m[4] * v.y + m[8] * v.z, m[1] * v.x + m[5] * v.y + m[9] * v.z, m[2] * v.x + m[6] * v.y + m[10] * v.z};
    }
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

/// One object of a frame: a contiguous run of the frame's triangles and the
/// world transform already applied to them (so a refit/rebuild choice can be per object).
struct ObjectInstance {
    std::string name;
    std::uint32_t first_triangle = 0;
    std::uint32_t triangle_count = 0;
    Transform transform;
    bool animated = false;
};

/// Triangle mesh with optional per-face material ids (as read from one PLY/OBJ file).
struct Mesh {
    std::vector<Vec3f> vertices;
    std::vector<std::array<std::uint32_t, 3>> faces;
    std::vector<std::uint32_t> face_material;   ///< empty, or one id per face into `materials`
    std::vector<Material> materials;

    /// Flattened world-space triangles (one per face).
    std::vector<Trianglef> triangles() const {
        std::vector<Trianglef> t(faces.size());
        for (std::size_t i = 0; i < faces.size(); ++i)
            t[i] = {vertices[faces[i][0]], vertices[faces[i][1]], vertices[faces[i][2]]};
        return t;
    }
    AABBf bounds() const { AABBf b; for (const auto& v : vertices) b.extend(v); return b; }
};

/// How the triangles of a scene move from frame to frame (UNC benchmark classes).
enum class Motion { none, rigid, hierarchical, semi_hierarchical, incoherent };

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
    std::vector<Trianglef> triangles;
    std::vector<std::uint32_t> material;
    std::vector<ObjectInstance> objects;
    Camera camera;
    double time = 0;   ///< seconds since the animation's start
};

/// Static description of an animated scene.
struct SceneInfo {
    std::string name;
    Motion motion = Motion::none;
    bool topology_changes = false;   ///< triangle count or connectivity changes between frames
    std::size_t frames = 1;
    std::vector<Material> materials;
    std::vector<Light> lights;
};

/// An animated scene: a fixed number of frames, each evaluated on demand.
/// Implementations: frame sequences (io/frames.hpp), BART (io/bart.hpp); the study's procedural scenes (bench/scenes).
class Scene {
public:
    virtual ~Scene() = default;
    virtual const SceneInfo& info() const = 0;
    std::size_t frame_count() const { return info().frames; }
    /// Evaluates frame `i` (0 <= i < frame_count()) into `out`, reusing its capacity.
    /// Throws LoadError (file scenes) or std::out_of_range.
    virtual void frame(std::size_t i, Frame& out) = 0;
};

} // namespace dynbvh::io
