// "What accuracy costs in time": every knob that buys tree quality or numerical robustness, one
// setting at a time, measured together (build ms, trace ms, SAH, memory) and compared hit for hit
// with the default settings (PLOC r = 5, robust box test, watertight triangles).
#pragma once

#include <string>
#include <vector>

#include "backend.hpp"
#include "builders.hpp"
#include "options.hpp"
#include "runner.hpp"

namespace dynbvh::study {

struct SweepSetting {
    std::string group;    ///< the knob
    std::string value;    ///< its value, as a label
    BuilderSpec spec;
    bool ordered = true;  ///< values form a scale (radius 1..64) rather than alternatives (box tests)
};

/// The settings of the sweep (`small`: fewer values per knob, for --quick). Embree builders are
/// included when available, for the crossover comparison.
std::vector<SweepSetting> sweep_settings(bool small, bool embree);

/// The setting every other is compared with.
BuilderSpec sweep_reference();

/// Runs the sweep on `scene_specs` (first resolution of opt.resolutions, the study's frame
/// selection, one repetition) and stores it in `res`.
void run_sweep(const Options& opt, const Backend& backend, const std::vector<std::string>& scene_specs, StudyResults& res);

} // namespace dynbvh::study
