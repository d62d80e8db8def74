#include "crossover.hpp"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <limits>

namespace dynbvh::study {

std::vector<Segment> lower_envelope(const std::vector<CostLine>& lines) {
    std::vector<Segment> env;
    if (lines.empty()) return env;
    const double inf = std::numeric_limits<double>::infinity();
    // Start: the cheapest line at 0 rays.
    std::size_t cur = 0;
    for (std::size_t i = 1; i < lines.size(); ++i) {
        const auto& a = lines[i];
        const auto& b = lines[cur];
        if (a.build_ms < b.build_ms || (a.build_ms == b.build_ms && a.trace_ms_per_ray < b.trace_ms_per_ray)) cur = i;
    }
    double at = 0;
    for (std::size_t guard = 0; guard <= lines.size(); ++guard) {
        // The next line to undercut the current one: a smaller slope crossing it at the smallest R >= at.
        std::size_t next = lines.size();
        double best = inf;
        for (std::size_t j = 0; j < lines.size(); ++j) {
            if (j == cur || !(lines[j].trace_ms_per_ray < lines[cur].trace_ms_per_ray)) continue;
            const double r = (lines[j].build_ms - lines[cur].build_ms) / (lines[cur].trace_ms_per_ray - lines[j].trace_ms_per_ray);
            const double rr = r < at ? at : r;
            if (rr < best || (rr == best && next < lines.size() && lines[j].trace_ms_per_ray < lines[next].trace_ms_per_ray)) {
                best = rr;
                next = j;
            }
        }
        if (next == lines.size()) {
            env.push_back({lines[cur].label, at, inf});
            break;
        }
        if (best > at) env.push_back({lines[cur].label, at, best});
        at = best;
        cur = next;
    }
    return env;
}

double lowest_at(const std::vector<CostLine>& lines, double rays) {
    double best = std::numeric_limits<double>::infinity();
    for (const auto& l : lines) best = std::min(best, l.at(rays));
    return best;
}

std::string format_rays(double rays) {
    char buf[32];
    if (!std::isfinite(rays)) return "inf";
    if (rays >= 1e6) std::snprintf(buf, sizeof buf, "%.3g M", rays / 1e6);
    else if (rays >= 1e3) std::snprintf(buf, sizeof buf, "%.3g k", rays / 1e3);
    else std::snprintf(buf, sizeof buf, "%.0f", rays);
    return buf;
}

std::string envelope_sentence(const std::string& scene, const std::vector<Segment>& env, const std::string& what) {
    std::string s = "On " + scene + (what.empty() ? "" : " (" + what + ")") + ", ";
    if (env.empty()) return s + "nothing was measured.";
    if (env.size() == 1) return s + env[0].label + " gives the lowest frame time at every ray count.";
    s += env[0].label + " gives the lowest frame time below " + format_rays(env[0].to) + (env[0].to >= 1e3 ? "rays/frame" : " rays/frame");
    for (std::size_t i = 1; i + 1 < env.size(); ++i)
        s += "; " + env[i].label + " from " + format_rays(env[i].from) + " to " + format_rays(env[i].to);
    s += "; " + env.back().label + " above.";
    return s;
}

} // namespace dynbvh::study
