/// @file scenes/lattice.hpp
/// A static bench scene of long thin triangles: a lattice of thin square beams along three
/// directions, k x k beams per direction, each running through the whole scene, the lattice
/// turned off every axis (so each beam's side triangles are long, thin and diagonal: their
/// boxes are huge against their area, the hard case for BVHs and for box-based culling).
/// Each beam's four sides are cut into s segments along its length (aspect ratio about
/// 1 : (spacing * s / width / 2)): 8 s + 4 triangles per beam, 3 k^2 (8 s + 4) in all. Not one of the animated
/// built-in scenes: the benches trace it beside them (`lattice`), as issue 11/12 ask.
#pragma once

#include <cmath>
#include <cstddef>
#include <cstdint>
#include <vector>

#include <dynbvh/io/scene.hpp>
#include <dynbvh/triangle.hpp>

namespace dynbvh::scenes {

/// Lattice size and shape: `beams` per direction and side (beams^2 per direction), beam width
/// relative to the spacing between beams, and the rotation (radians) about y then x.
struct LatticeConfig {
    std::uint32_t beams = 22;       ///< beams per side and direction
    std::uint32_t segments = 8;     ///< segments along each beam: 3 * 22^2 * 68 = 98,736 triangles
    float width = 0.08f;            ///< beam width / spacing (side triangles about 34 times longer than wide)
    float yaw = 0.52f, pitch = 0.37f;
};

/// The lattice's triangles (centred on the origin, extent about [-1, 1]^3 before the rotation) and a
/// camera a little outside it, looking at its centre. O(beams^2).
inline io::Frame lattice(const LatticeConfig& cfg = {}) {
    io::Frame f;
    const std::uint32_t k = cfg.beams < 1 ? 1 : cfg.beams;
    const float spacing = 2.0f / float(k), half = 0.5f * cfg.width * spacing;
    const float cy = std::cos(cfg.yaw), sy = std::sin(cfg.yaw), cx = std::cos(cfg.pitch), sx = std::sin(cfg.pitch);
    auto rotate = [&](Vec3f p) {
        const Vec3f q{cy * p.x + sy * p.z, p.y, -sy * p.x + cy * p.z};   // about y
        return Vec3f{q.x, cx * q.y - sx * q.z, sx * q.y + cx * q.z};      // about x
    };
    const std::uint32_t segs = cfg.segments < 1 ? 1 : cfg.segments;
    f.triangles.reserve(std::size_t(3) * k * k * (8 * segs + 4));
    for (int axis = 0; axis < 3; ++axis) {
        const int a1 = (axis + 1) % 3, a2 = (axis + 2) % 3;
        for (std::uint32_t i = 0; i < k; ++i)
            for (std::uint32_t j = 0; j < k; ++j) {
                // beam centre line along `axis` at (c1, c2) in the other two; offset per direction so beams
                // of different directions cross without sharing faces
                const float off = 0.5f * spacing * float(axis) / 3.0f;
                const float c1 = -1.0f + (float(i) + 0.5f) * spacing + off, c2 = -1.0f + (float(j) + 0.5f) * spacing + off;
                // corner c of cross-section s: bit 0 / 1 of c = side in a1 / a2; sections at even steps along axis
                auto corner = [&](std::uint32_t sec, int c) {
                    float p[3];
                    p[axis] = -1.0f + 2.0f * float(sec) / float(segs);
                    p[a1] = c1 + ((c & 1) ? half : -half);
                    p[a2] = c2 + ((c & 2) ? half : -half);
                    return rotate({p[0], p[1], p[2]});
                };
                auto quad = [&](Vec3f a, Vec3f b, Vec3f c, Vec3f d) {   // a b c d around the quad
                    f.triangles.push_back({a, b, c});
                    f.triangles.push_back({a, c, d});
                };
                static constexpr int ring[5] = {0, 1, 3, 2, 0};   // the four sides, around the cross-section
                for (std::uint32_t sec = 0; sec < segs; ++sec)
                    for (int e = 0; e < 4; ++e)
                        quad(corner(sec, ring[e]), corner(sec + 1, ring[e]), corner(sec + 1, ring[e + 1]), corner(sec, ring[e + 1]));
                quad(corner(0, 0), corner(0, 2), corner(0, 3), corner(0, 1));                  // end caps
                quad(corner(segs, 0), corner(segs, 1), corner(segs, 3), corner(segs, 2));
            }
    }
    f.camera.from = {0.35f, 0.6f, 3.2f};
    f.camera.at = {0.0f, 0.0f, 0.0f};
    f.camera.up = {0.0f, 1.0f, 0.0f};
    f.camera.fov_y_deg = 50.0f;
    return f;
}

} // namespace dynbvh::scenes
