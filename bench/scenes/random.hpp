/// @file scenes/random.hpp
/// The built-in scenes' random numbers: SplitMix64 (Steele, Lea, Flood 2014) and a
/// few helpers on top of it. Pure integer arithmetic plus exact conversions, so a
/// seed gives the same sequence on every compiler and standard library (unlike the
/// std:: distributions, whose output is implementation-defined).
#pragma once

#include <cmath>
#include <cstdint>

#include <dynbvh/vec.hpp>

namespace dynbvh::scenes {

/// SplitMix64 generator: 64-bit state, period 2^64, passes BigCrush. O(1) per draw.
class SplitMix64 {
public:
    explicit constexpr SplitMix64(std::uint64_t seed = 1) noexcept : state_(seed) {}

    /// Next 64 uniformly distributed bits.
    constexpr std::uint64_t next() noexcept {
        std::uint64_t z = (state_ += 0x9E3779B97F4A7C15ull);
        z = (z ^ (z >> 30)) * 0xBF58476D1CE4E5B9ull;
        z = (z ^ (z >> 27)) * 0x94D049BB133111EBull;
        return z ^ (z >> 31);
    }
    /// Uniform double in [0, 1) from the top 53 bits.
    constexpr double uniform() noexcept { return double(next() >> 11) * 0x1.0p-53; }
    /// Uniform double in [lo, hi).
    constexpr double uniform(double lo, double hi) noexcept { return lo + (hi - lo) * uniform(); }
    /// Uniform float in [lo, hi).
    constexpr float uniformf(float lo, float hi) noexcept { return float(uniform(lo, hi)); }
    /// Uniform integer in [0, n) (n > 0; the modulo bias is below 2^-40 for n < 2^24).
    constexpr std::uint32_t below(std::uint32_t n) noexcept { return std::uint32_t(next() % n); }
    /// Uniformly distributed unit vector (rejection from the cube; no transcendental calls).
    Vec3f unit_vector() noexcept {
        for (;;) {
            const double x = uniform(-1, 1), y = uniform(-1, 1), z = uniform(-1, 1);
            const double l2 = x * x + y * y + z * z;
            if (l2 > 1e-6 && l2 <= 1) {
                const double s = 1 / std::sqrt(l2);
                return {float(x * s), float(y * s), float(z * s)};
            }
        }
    }
    /// A generator for a sub-stream (e.g. one per object), independent of how many
    /// numbers this one has drawn: derived from the seed and `stream` only.
    static constexpr SplitMix64 derive(std::uint64_t seed, std::uint64_t stream) noexcept {
        SplitMix64 g(seed ^ (stream * 0xD1B54A32D192ED03ull));
        g.next();
        return SplitMix64(g.next());
    }

private:
    std::uint64_t state_;
};

/// Stateless hash of two integers to a float in [0, 1): jitter that does not depend on visiting order.
constexpr float hash01(std::uint64_t seed, std::uint64_t a, std::uint64_t b = 0) noexcept {
    SplitMix64 g(seed ^ (a * 0x9E3779B97F4A7C15ull) ^ (b * 0xC2B2AE3D27D4EB4Full));
    return float(g.next() >> 40) * 0x1.0p-24f;
}

} // namespace dynbvh::scenes
