// OUT/report.md: the tables, conclusions computed from the data, SVG figures (like the thesis's
// figures 5.5-5.12) and the PNG renders; plus the conclusions as plain text for the terminal.
#pragma once

#include <string>
#include <vector>

#include "runner.hpp"

namespace dynbvh::study {

/// Sentences computed from the study's measurements (best builder per scene and resolution,
/// crossovers, the thesis and Embree comparisons).
std::vector<std::string> study_conclusions(const StudyResults& r);
/// Sentences computed from --effects auto (per scene and resolution: rays per kind, each builder's
/// tracing time per kind relative to the fastest, whether the better tree pays off more for secondary rays).
std::vector<std::string> effects_conclusions(const StudyResults& r);
/// Sentences computed from the sweep (per scene and knob).
std::vector<std::string> sweep_conclusions(const StudyResults& r);

/// Writes every SVG figure into r.options.out and report.md; returns the report's path.
std::string write_report(const StudyResults& r);

} // namespace dynbvh::study
