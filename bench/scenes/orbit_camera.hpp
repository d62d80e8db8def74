/// @file scenes/orbit_camera.hpp
/// The built-in scenes' animated camera: circles a target point at a fixed distance
/// and elevation, so every frame shows the whole scene from a slowly changing side.
#pragma once

#include <cmath>
#include <numbers>

#include <dynbvh/io/scene.hpp>

namespace dynbvh::scenes {

/// Camera on a horizontal circle around `target` (y is up).
struct OrbitCamera {
    Vec3f target{0, 0, 0};
    float distance = 10;          ///< from target, scene units
    float elevation = 0.35f;      ///< radians above the horizontal plane through target
    float start_angle = 0;        ///< radians, azimuth at frame 0 (0: camera on the +x side)
    float angular_speed = 0.004f; ///< radians per frame
    float fov_y_deg = 45;

    /// Distance at which a sphere of `radius` fits the vertical field of view `fov_y_deg`, with `margin`.
    static float framing_distance(float radius, float fov_y_deg, float margin = 1.15f) noexcept {
        return margin * radius / std::sin(0.5f * fov_y_deg * float(std::numbers::pi) / 180.0f);
    }
    /// The camera at (possibly fractional) frame `f`.
    io::Camera at(double f) const noexcept {
        const float az = start_angle + angular_speed * float(f);
        const float ce = std::cos(elevation);
        io::Camera c;
        c.at = target;
        c.from = target + Vec3f{distance * ce * std::cos(az), distance * std::sin(elevation), distance * ce * std::sin(az)};
        c.up = {0, 1, 0};
        c.fov_y_deg = fov_y_deg;
        return c;
    }
};

} // namespace dynbvh::scenes
