/// @file scenes/rigid.hpp
/// Rigid-body pose for the built-in scenes: a unit quaternion rotation plus a position,
/// turned into the io::Transform a Frame's objects carry. Just enough for balls,
/// shards and a spinning ball; no inertia tensors.
#pragma once

#include <cmath>

#include <dynbvh/io/scene.hpp>
#include <dynbvh/vec.hpp>

namespace dynbvh::scenes {

/// Unit quaternion w + xi + yj + zk.
struct Quat {
    float w = 1, x = 0, y = 0, z = 0;

    /// Rotation by `angle` radians about the unit vector `axis`.
    static Quat axis_angle(Vec3f axis, float angle) noexcept {
        const float s = std::sin(angle * 0.5f);
        return {std::cos(angle * 0.5f), axis.x * s, axis.y * s, axis.z * s};
    }
    friend Quat operator*(const Quat& a, const Quat& b) noexcept {
        return {a.w * b.w - a.x * b.x - a.y * b.y - a.z * b.z, a.w * b.x + a.x * b.w + a.y * b.z - a.z * b.y,
                a.w * b.y - a.x * b.z + a.y * b.w + a.z * b.x, a.w * b.z + a.x * b.y - a.y * b.x + a.z * b.w};
    }
    Quat normalized() const noexcept {
        const float l = std::sqrt(w * w + x * x + y * y + z * z);
        return {w / l, x / l, y / l, z / l};
    }
    /// Advances by angular velocity `omega` (radians per unit time) over `dt`, exactly for constant omega.
    Quat integrate(Vec3f omega, float dt) const noexcept {
        const float a = length(omega) * dt;
        if (a < 1e-12f) return *this;
        return (axis_angle(omega * (dt / a), a) * *this).normalized();
    }
};

/// A rigid pose: world point = rotation * (rest point - pivot) + position.
struct Pose {
    Quat rotation;
    Vec3f pivot{0, 0, 0};      ///< the rest-space point that `position` moves
    Vec3f position{0, 0, 0};

    /// The pose as a column-major affine io::Transform acting on rest-space points.
    io::Transform transform() const noexcept {
        const Quat& q = rotation;
        const float xx = q.x * q.x, yy = q.y * q.y, zz = q.z * q.z, xy = q.x * q.y, xz = q.x * q.z, yz = q.y * q.z;
        const float wx = q.w * q.x, wy = q.w * q.y, wz = q.w * q.z;
        io::Transform t;
        t.m = {1 - 2 * (yy + zz), 2 * (xy + wz), 2 * (xz - wy), 0,
               2 * (xy - wz), 1 - 2 * (xx + zz), 2 * (yz + wx), 0,
               2 * (xz + wy), 2 * (yz - wx), 1 - 2 * (xx + yy), 0,
               0, 0, 0, 1};
        const Vec3f rp = t.apply_vector(pivot);
        t.m[12] = position.x - rp.x;
        t.m[13] = position.y - rp.y;
        t.m[14] = position.z - rp.z;
        return t;
    }
};

} // namespace dynbvh::scenes
