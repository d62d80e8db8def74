// SPDX-License-Identifier: MIT
/// @file io/bart_spline.hpp
/// The keyframe interpolation of BART (Lext, Assarsson, Möller 2001, "A Benchmark for
/// Animated Ray Tracing"): Kochanek–Bartels (tension/continuity/bias) cubic Hermite
/// splines for translation and scale, and their quaternion counterpart (squad with
/// Kochanek–Bartels tangents in the quaternion log space) for rotation.
/// Kochanek & Bartels, "Interpolating Splines with Local Tension, Continuity, and Bias
/// Control", SIGGRAPH 1984; Shoemake, "Animating Rotation with Quaternion Curves", 1985.
///
/// BART conventions (kept here so that every frame matches the benchmark):
///  - a track needs at least 4 keys; the first and the last only shape the end tangents,
///    so the curve runs from key 1 to key n-2 and is clamped to those values outside;
///  - segment i interpolates keys i+1 -> i+2; time t is served by the first segment (in key
///    order) that ends after t, so zero-length segments are skipped, and keys that jump back in
///    time (the Robots scene has such tracks) are unreachable, exactly as in the reference code;
///  - t <= time of key 1 gives key 1; t >= end of the last segment gives key n-2.
/// Rotation keys are flipped to the short arc as the reference does it, lazily: key k >= 2 is
/// negated when it points away from key k-1 (as already flipped), key 1 is never compared with
/// key 0, and the tangent of segment i sees key i+3 unflipped. This matters only for tracks whose
/// consecutive keys are more than 180 degrees apart (in BART: the Robots camera) and keeps such
/// camera paths identical to the benchmark's.
#pragma once

#include <algorithm>
#include <array>
#include <cmath>
#include <cstddef>
#include <vector>

namespace dynbvh::io::bart {

/// One key of a translation or scale track: value at time `t` (seconds) plus the
/// Kochanek–Bartels shape parameters at that key (all 0 = Catmull–Rom).
struct VectorKey {
    /// Time of the key in seconds (the file's clock).
    double t = 0;
    /// Value at `t`.
    std::array<double, 3> value{};
    /// @{
    /// Kochanek–Bartels tension, continuity and bias at this key (all 0: Catmull–Rom).
    double tension = 0, continuity = 0, bias = 0;
    /// @}
};

/// One key of a rotation track: `angle` radians about `axis` (any length > 0; normalised).
struct RotationKey {
    /// Time of the key in seconds (the file's clock).
    double t = 0;
    /// Rotation axis (any length > 0).
    std::array<double, 3> axis{1, 0, 0};
    /// Rotation angle in radians.
    double angle = 0;
    /// @{
    /// Kochanek–Bartels tension, continuity and bias at this key (all 0: Catmull–Rom).
    double tension = 0, continuity = 0, bias = 0;
    /// @}
};

/// Quaternion w + xi + yj + zk (unit quaternions represent rotations).
struct Quaternion {
    /// @{
    /// The components w + xi + yj + zk; the default is the identity rotation.
    double w = 1, x = 0, y = 0, z = 0;
    /// @}

    /// Hamilton product: a * b rotates by b, then by a.
    friend Quaternion operator*(const Quaternion& a, const Quaternion& b) noexcept {
        return {a.w * b.w - a.x * b.x - a.y * b.y - a.z * b.z, a.w * b.x + a.x * b.w + a.y * b.z - a.z * b.y,
                a.w * b.y - a.x * b.z + a.y * b.w + a.z * b.x, a.w * b.z + a.x * b.y - a.y * b.x + a.z * b.w};
    }
    /// Scaling by `s`.
    friend Quaternion operator*(double s, const Quaternion& q) noexcept { return {s * q.w, s * q.x, s * q.y, s * q.z}; }
    /// Component-wise sum.
    friend Quaternion operator+(const Quaternion& a, const Quaternion& b) noexcept {
        return {a.w + b.w, a.x + b.x, a.y + b.y, a.z + b.z};
    }
    /// Component-wise difference.
    friend Quaternion operator-(const Quaternion& a, const Quaternion& b) noexcept {
        return {a.w - b.w, a.x - b.x, a.y - b.y, a.z - b.z};
    }
    /// 4D dot product (negative: q and -q, the same rotation, are nearer; used to pick the short arc).
    friend double dot(const Quaternion& a, const Quaternion& b) noexcept { return a.w * b.w + a.x * b.x + a.y * b.y + a.z * b.z; }
    /// w - xi - yj - zk: the inverse of a unit quaternion.
    Quaternion conjugate() const noexcept { return {w, -x, -y, -z}; }

    /// Rotation of `angle` radians about `axis` (normalised here; a zero axis gives the identity).
    static Quaternion from_axis_angle(const std::array<double, 3>& axis, double angle) noexcept {
        const double len = std::sqrt(axis[0] * axis[0] + axis[1] * axis[1] + axis[2] * axis[2]);
        if (!(len > 0)) return {};
        const double s = std::sin(0.5 * angle) / len;
        return {std::cos(0.5 * angle), axis[0] * s, axis[1] * s, axis[2] * s};
    }
    /// log of a unit quaternion: (0, theta * axis) for q = (cos theta, sin theta * axis).
    Quaternion log() const noexcept {
        const double vlen = std::sqrt(x * x + y * y + z * z);
        const double theta = std::atan2(vlen, w);   // stable for tiny angles, unlike acos(w)
        const double k = vlen > 1e-300 ? theta / vlen : 1.0;
        return {0, k * x, k * y, k * z};
    }
    /// exp of a pure quaternion (0, v): (cos |v|, sin |v| * v / |v|).
    Quaternion exp() const noexcept {
        const double theta = std::sqrt(x * x + y * y + z * z);
        const double k = theta > 1e-12 ? std::sin(theta) / theta : 1.0;
        return {std::cos(theta), k * x, k * y, k * z};
    }
    /// Row-major 3x3 rotation matrix of this (unit) quaternion.
    std::array<double, 9> matrix() const noexcept {
        const double n = w * w + x * x + y * y + z * z;
        const double s = n > 0 ? 2.0 / n : 0.0;
        const double xx = x * x * s, yy = y * y * s, zz = z * z * s, xy = x * y * s, xz = x * z * s, yz = y * z * s,
                     wx = w * x * s, wy = w * y * s, wz = w * z * s;
        return {1 - yy - zz, xy - wz, xz + wy, xy + wz, 1 - xx - zz, yz - wx, xz - wy, yz + wx, 1 - xx - yy};
    }
};

/// Spherical linear interpolation from p (u = 0) to q (u = 1), along the arc as given
/// (no hemisphere flip: squad needs the exact arcs it was built with).
inline Quaternion slerp(double u, const Quaternion& p, const Quaternion& q) noexcept {
    // angle between p and q, stable for nearly equal quaternions: 2 atan2(|p - q|, |p + q|)
    const Quaternion d = p - q, e = p + q;
    const double angle = 2 * std::atan2(std::sqrt(dot(d, d)), std::sqrt(dot(e, e)));
    const double s = std::sin(angle);
    if (std::abs(s) < 1e-12) return p;
    const double a = std::sin((1 - u) * angle) / s, b = std::sin(u * angle) / s;
    return a * p + b * q;
}

namespace detail {
/// Where time t falls: segment index and local parameter in [0, 1). Returns false when t
/// is clamped to the first (`at_end` false) or last (`at_end` true) interior key.
/// `reach[i]` = max(tmax[0..i]), so that the first segment ending after t is an upper_bound.
inline bool locate(const std::vector<double>& tmin, const std::vector<double>& tmax, const std::vector<double>& reach,
                   double t, std::size_t& seg, double& u, bool& at_end) noexcept {
    if (!(tmin.front() < t)) { at_end = false; return false; }    // also NaN time -> first key
    if (!(t < tmax.back())) { at_end = true; return false; }
    // first segment whose end lies beyond t; it exists (the last one does) and starts at or
    // before t (it starts where the previous segment ends), so u is in [0, 1)
    seg = static_cast<std::size_t>(std::upper_bound(reach.begin(), reach.end(), t) - reach.begin());
    u = (t - tmin[seg]) / (tmax[seg] - tmin[seg]);
    return true;
}
inline void add_segment(std::vector<double>& tmin, std::vector<double>& tmax, std::vector<double>& reach, double t1, double t2) {
    tmin.push_back(t1);
    tmax.push_back(t2);
    reach.push_back(reach.empty() ? t2 : std::max(reach.back(), t2));
}
/// Kochanek–Bartels tangent weights for the segment k1 -> k2 with neighbours k0, k3:
/// outgoing tangent at k1 = out_prev * (P1 - P0) + out_next * (P2 - P1), incoming at k2 =
/// in_prev * (P2 - P1) + in_next * (P3 - P2), including the uneven-spacing adjustment.
struct TcbWeights { double out_prev, out_next, in_prev, in_next; };
template <class Key>
TcbWeights tcb_weights(const Key& k0, const Key& k1, const Key& k2, const Key& k3) noexcept {
    const double d20 = k2.t - k0.t, d31 = k3.t - k1.t, d21 = k2.t - k1.t;
    // as the reference: only a zero spacing (never on a reachable segment) is guarded
    const double adj0 = d20 != 0 ? 2 * d21 / d20 : 0.0, adj1 = d31 != 0 ? 2 * d21 / d31 : 0.0;
    TcbWeights w;
    w.out_prev = 0.5 * adj0 * (1 - k1.tension) * (1 + k1.continuity) * (1 + k1.bias);
    w.out_next = 0.5 * adj0 * (1 - k1.tension) * (1 - k1.continuity) * (1 - k1.bias);
    w.in_prev = 0.5 * adj1 * (1 - k2.tension) * (1 - k2.continuity) * (1 + k2.bias);
    w.in_next = 0.5 * adj1 * (1 - k2.tension) * (1 + k2.continuity) * (1 - k2.bias);
    return w;
}
} // namespace detail

/// Kochanek–Bartels spline through 3-vectors (BART `transl` and `scale` tracks).
/// Construction O(n), evaluation O(log n). Interpolates the interior keys exactly.
class VectorSpline {
public:
    VectorSpline() = default;
    /// `keys.size() >= 4` (the loader checks).
    explicit VectorSpline(const std::vector<VectorKey>& keys) {
        const std::size_t n = keys.size();
        first_ = keys[1].value;
        last_ = keys[n - 2].value;
        for (std::size_t i = 0; i + 3 < n; ++i) {
            const VectorKey &k0 = keys[i], &k1 = keys[i + 1], &k2 = keys[i + 2], &k3 = keys[i + 3];
            const auto w = detail::tcb_weights(k0, k1, k2, k3);
            Cubic c;
            for (std::size_t a = 0; a < 3; ++a) {
                const double d = k2.value[a] - k1.value[a];
                const double tout = w.out_next * d + w.out_prev * (k1.value[a] - k0.value[a]);
                const double tin = w.in_next * (k3.value[a] - k2.value[a]) + w.in_prev * d;
                c.c0[a] = k1.value[a];
                c.c1[a] = tout;
                c.c2[a] = 3 * d - 2 * tout - tin;
                c.c3[a] = -2 * d + tout + tin;
            }
            polys_.push_back(c);
            detail::add_segment(tmin_, tmax_, reach_, k1.t, k2.t);
        }
    }
    /// True for a default-constructed spline (no segment).
    bool empty() const noexcept { return polys_.empty(); }
    /// Value at time t (seconds, the file's clock), clamped to [key 1, key n-2].
    std::array<double, 3> operator()(double t) const noexcept {
        std::size_t i = 0;
        double u = 0;
        bool at_end = false;
        if (!detail::locate(tmin_, tmax_, reach_, t, i, u, at_end)) return at_end ? last_ : first_;
        const Cubic& c = polys_[i];
        std::array<double, 3> r;
        for (std::size_t a = 0; a < 3; ++a) r[a] = c.c0[a] + u * (c.c1[a] + u * (c.c2[a] + u * c.c3[a]));
        return r;
    }

private:
    struct Cubic { std::array<double, 3> c0, c1, c2, c3; };
    std::vector<Cubic> polys_;
    std::vector<double> tmin_, tmax_, reach_;
    std::array<double, 3> first_{}, last_{};
};

/// Kochanek–Bartels rotation spline (BART `rot` tracks): keys become unit quaternions (short
/// arcs chosen as in the reference, see above), tangents are built in log space with the same
/// TCB weights as the vector spline, and each segment is a squad
/// Q(u) = slerp(2u(1-u), slerp(u, q1, q2), slerp(u, a, b)). Interpolates the interior keys exactly.
class RotationSpline {
public:
    RotationSpline() = default;
    /// `keys.size() >= 4` (the loader checks).
    explicit RotationSpline(const std::vector<RotationKey>& keys) {
        const std::size_t n = keys.size();
        std::vector<Quaternion> raw(n), q(n);
        for (std::size_t i = 0; i < n; ++i) {
            raw[i] = q[i] = Quaternion::from_axis_angle(keys[i].axis, keys[i].angle);
            if (i >= 2 && dot(q[i - 1], q[i]) < 0) q[i] = -1.0 * q[i];   // the short arc from key i-1
        }
        first_ = q[1];
        last_ = q[n - 2];
        for (std::size_t i = 0; i + 3 < n; ++i) {
            const auto w = detail::tcb_weights(keys[i], keys[i + 1], keys[i + 2], keys[i + 3]);
            const Quaternion &q0 = q[i], &q1 = q[i + 1], &q2 = q[i + 2], &q3 = raw[i + 3];
            const Quaternion log12 = (q1.conjugate() * q2).log();
            const Quaternion tout = w.out_next * log12 + w.out_prev * (q0.conjugate() * q1).log();
            const Quaternion tin = w.in_next * (q2.conjugate() * q3).log() + w.in_prev * log12;
            Squad s;
            s.p = q1;
            s.q = q2;
            s.a = q1 * (0.5 * (tout - log12)).exp();
            s.b = q2 * (0.5 * (log12 - tin)).exp();
            segs_.push_back(s);
            detail::add_segment(tmin_, tmax_, reach_, keys[i + 1].t, keys[i + 2].t);
        }
    }
    /// True for a default-constructed spline (no segment).
    bool empty() const noexcept { return segs_.empty(); }
    /// Rotation at time t (seconds, the file's clock), clamped to [key 1, key n-2].
    Quaternion operator()(double t) const noexcept {
        std::size_t i = 0;
        double u = 0;
        bool at_end = false;
        if (!detail::locate(tmin_, tmax_, reach_, t, i, u, at_end)) return at_end ? last_ : first_;
        const Squad& s = segs_[i];
        return slerp(2 * u * (1 - u), slerp(u, s.p, s.q), slerp(u, s.a, s.b));
    }

private:
    struct Squad { Quaternion p, a, b, q; };
    std::vector<Squad> segs_;
    std::vector<double> tmin_, tmax_, reach_;
    Quaternion first_{}, last_{};
};

} // namespace dynbvh::io::bart
