/// @file scenes/options.hpp
/// The options every built-in scene takes: the random seed and a triangle-count scale.
#pragma once

#include <cmath>
#include <cstdint>
#include <stdexcept>
#include <string>
#include <string_view>

namespace dynbvh::scenes {

/// Options shared by the built-in scenes. Designated-initialiser friendly: `{.seed = 7, .scale = 0.1}`.
struct BuiltinOptions {
    std::uint64_t seed = 1;   ///< same seed => bit-identical frames (for one build); another seed => other frames
    double scale = 1.0;       ///< multiplies triangle counts (0 < scale <= 16); motion, frame count and size stay
};

/// Throws std::invalid_argument naming the scene when `opt.scale` is not in (0, 16].
inline void validate(const BuiltinOptions& opt, std::string_view scene) {
    if (!(opt.scale > 0 && opt.scale <= 16))
        throw std::invalid_argument("dynbvh::scenes::" + std::string(scene) + ": scale " + std::to_string(opt.scale) +
                                    " is outside (0, 16]");
}

/// Side of a square grid of quads holding about `scale * triangles` triangles (2 per quad), at least `min`.
inline std::uint32_t grid_side(double triangles, double scale, std::uint32_t min = 2) {
    const double s = std::round(std::sqrt(scale * triangles / 2));
    return s < min ? min : static_cast<std::uint32_t>(s);
}

} // namespace dynbvh::scenes
