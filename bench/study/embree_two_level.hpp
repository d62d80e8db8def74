// embree-two-level: Embree 3's own two-level scenes as the reference for our two-level: one Embree scene
// per object of the frame (rigid objects built once in object space, taken from their first frame through
// the inverse of its transform, like ours; deforming objects, animated with an identity transform,
// refitted every frame as embree-refit does), one instance geometry per object in a top scene rebuilt
// every frame (RTC_BUILD_QUALITY_LOW). Vertex copies are untimed (prepare), as for every Embree variant.
#pragma once

#include <memory>

#include "builders.hpp"

namespace dynbvh::study {

/// The Accel for `embree-two-level`; throws std::runtime_error in a binary without Embree 3.
std::unique_ptr<Accel> make_embree_two_level_accel(const BuilderSpec& spec, const Backend& backend);

} // namespace dynbvh::study
