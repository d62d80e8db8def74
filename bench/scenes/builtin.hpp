/// @file scenes/builtin.hpp
/// The built-in animated scenes, generated in memory from a seed, so that the study
/// and the examples run anywhere with no files. Each follows a UNC Dynamic Scene
/// Benchmark scene in size and kind of motion:
///
/// | name             | triangles        | frames | motion            | topology |
/// |------------------|------------------|--------|-------------------|----------|
/// | `cloth-ball`     | 92,360           | 94     | incoherent        | kept     |
/// | `n-body`         | 146,480          | 76     | hierarchical      | kept     |
/// | `breaking`       | 251,978 (+~3 %)  | 16     | semi-hierarchical | changes  |
/// | `large-breaking` | 1,599,852 (+~4 %)| 45     | semi-hierarchical | changes  |
/// | `funnel`         | 18,462           | 150    | incoherent        | kept     |
///
/// (Breaking scenes gain fracture faces as they break: the figure in brackets is the growth
/// by the last frame at scale 1; it depends a little on the seed, and is relatively larger at
/// small scales.) All counts scale with `scale`.
///
/// `auto scene = dynbvh::scenes::make_builtin("cloth-ball", {.seed = 7, .scale = 0.1});`
#pragma once

#include <array>
#include <memory>
#include <span>
#include <stdexcept>
#include <string>
#include <string_view>

#include <dynbvh/io/scene.hpp>
#include "breaking.hpp"
#include "cloth_ball.hpp"
#include "funnel.hpp"
#include "n_body.hpp"
#include "options.hpp"

namespace dynbvh::scenes {

/// Names accepted by make_builtin, in the order of the table above.
inline std::span<const std::string_view> builtin_names() noexcept {
    static constexpr std::array<std::string_view, 5> names = {"cloth-ball", "n-body", "breaking", "large-breaking", "funnel"};
    return names;
}

/// Creates the built-in scene `name`. Throws std::invalid_argument listing the valid names
/// for an unknown one, or for a scale outside (0, 16]. Construction precomputes the animation
/// (from ~0.05 s for n-body to ~1-2 s for large-breaking); frames are then O(triangles).
inline std::unique_ptr<io::Scene> make_builtin(std::string_view name, const BuiltinOptions& opt = {}) {
    if (name == "cloth-ball") return std::make_unique<ClothBall>(opt);
    if (name == "n-body") return std::make_unique<NBody>(opt);
    if (name == "breaking") return std::make_unique<Breaking>(BreakingConfig{}, opt);
    if (name == "large-breaking") return std::make_unique<Breaking>(BreakingConfig::large(), opt);
    if (name == "funnel") return std::make_unique<Funnel>(opt);
    std::string msg = "dynbvh::scenes::make_builtin: unknown scene '" + std::string(name) + "'; valid names:";
    for (std::string_view n : builtin_names()) {   // appended piecewise: GCC 12's -Wrestrict misfires on " " + string
        msg += ' ';
        msg += n;
    }
    throw std::invalid_argument(msg);
}

} // namespace dynbvh::scenes
