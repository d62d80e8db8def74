// Frame time as a function of rays per frame, and where each builder or setting starts to win.
// Model: frame_ms(R) = build_ms + R * trace_ms_per_ray, both measured (trace cost per ray from the
// total trace time over the total rays traced, all resolutions together). The lower envelope of
// these lines says which one gives the lowest frame time for every ray count.
#pragma once

#include <string>
#include <vector>

#include "results.hpp"

namespace dynbvh::study {

struct CostLine {
    std::string label;
    double build_ms = 0;
    double trace_ms_per_ray = 0;
    double at(double rays) const noexcept { return build_ms + rays * trace_ms_per_ray; }
};

/// One piece of the envelope: `label` is fastest for rays in [from, to) (to = +inf for the last).
struct Segment {
    std::string label;
    double from = 0, to = 0;
};

/// The lower envelope over rays >= 0, in increasing ray count. Ties go to the cheaper trace.
std::vector<Segment> lower_envelope(const std::vector<CostLine>& lines);

/// The lowest frame time of all lines at `rays` (the lower envelope's value there); +inf for no lines.
double lowest_at(const std::vector<CostLine>& lines, double rays);

/// "1.2 M", "350 k", "900".
std::string format_rays(double rays);

/// "On cloth-ball, lbvh gives the lowest frame time below 1.2 Mrays/frame; ploc from 1.2 M to 30 M; binned-sah above."
std::string envelope_sentence(const std::string& scene, const std::vector<Segment>& env, const std::string& what = "");

} // namespace dynbvh::study
