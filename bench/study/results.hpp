// The measurements the study takes and everything the writers (tables, JSON/CSV, plots,
// report) read: one FrameRecord per built and traced frame, grouped per scene x builder x resolution.
#pragma once

#include <algorithm>
#include <array>
#include <cstddef>
#include <cstdint>
#include <limits>
#include <optional>
#include <string>
#include <vector>

namespace dynbvh::study {

/// Image size in pixels; one primary ray per pixel.
struct Resolution {
    int width = 0, height = 0;
    std::size_t rays() const noexcept { return std::size_t(width) * std::size_t(height); }
    std::string str() const { return std::to_string(width) + "x" + std::to_string(height); }
    friend bool operator==(const Resolution&, const Resolution&) = default;
};

/// What `--effects auto` measured on one frame: the Whitted renderer (bench/render/whitted.hpp) run
/// after the study's own primary trace, over the same structure through single-ray queries.
/// Index 0..3 = primary, shadow, reflection, refraction (render::RayKind).
struct EffectsRecord {
    std::array<std::uint64_t, 4> rays{};   ///< rays traced per kind
    std::array<double, 4> ms{};            ///< tracing time per kind (each kind traced in its own passes)
    double shade_ms = 0;                   ///< shading, ray generation and queues (same for every builder, roughly)
    int depth = 0;                         ///< deepest bounce reached
    std::uint64_t total_rays() const noexcept { return rays[0] + rays[1] + rays[2] + rays[3]; }
    double total_ms() const noexcept { return ms[0] + ms[1] + ms[2] + ms[3]; }
};

/// Names of EffectsRecord's kinds, in index order.
inline constexpr std::array<const char*, 4> effect_kind_names{"primary", "shadow", "reflection", "refraction"};

/// What a strategy (`auto`: dynbvh::Dynamic, dynamic.hpp) did with its tree on one frame, from its
/// dynbvh::FrameReport. SAHs with Ct = 3, Ci = 2, like FrameRecord::sah.
struct StrategyRecord {
    std::string decision;              ///< "refit", "rebuild" or "swap"
    std::string reason;                ///< "none", "first_frame", "topology", "finiteness", "sah_growth", "amortized", "rebuild_ready"
    std::optional<double> sah_before;  ///< the previous tree refitted to this frame; none when there was none
    double sah_after = 0;              ///< the tree serving this frame (= FrameRecord::sah)
    double sah_rebuilt = 0;            ///< the serving tree's SAH right after its build (what the threshold multiplies)
    double threshold = 0;              ///< the sah rule's rebuild threshold
    std::string rule;                  ///< "amortized" or "sah"
    double loss_ms = 0;                ///< amortized: trace time estimated lost to refitting since the last rebuild
    double rebuild_cost_ms = 0;        ///< amortized: what a rebuild is taken to cost (the last one's time)
    double trust = 1;                  ///< amortized: share of SAH-predicted savings rebuilds delivered (FrameReport::trust)
    double elasticity = 1;             ///< amortized: e of trace time ~ SAH^e used by the loss estimates (FrameReport::elasticity)
    bool rebuild_started = false;      ///< async: a background rebuild started this frame
};

/// One frame of one run: build it (timed), trace one ray per pixel (timed), then the untimed metrics.
struct FrameRecord {
    std::uint32_t rep = 0;
    std::uint32_t frame = 0;          ///< frame index in the scene
    std::size_t triangles = 0;
    double build_ms = 0;
    double trace_ms = 0;
    std::optional<double> sah;        ///< SAH cost (Ct = 3, Ci = 2); none for Embree
    std::optional<std::size_t> memory_bytes;   ///< Bvh::memory_bytes; none for Embree
    std::size_t hits = 0;             ///< pixels whose ray hit something
    std::optional<EffectsRecord> effects;   ///< --effects auto only
    std::optional<StrategyRecord> strategy; ///< strategies (auto) only: the frame's decision
};

/// Summary of a list of frame records (all repetitions together).
struct Summary {
    std::size_t frames = 0;           ///< records (frames x repetitions)
    double total_build_ms = 0, total_trace_ms = 0;
    double mean_build_ms = 0, mean_trace_ms = 0;
    double fps = 0;                   ///< frames / (total build + total trace)
    double mrays_per_s = 0;           ///< rays traced / total trace time
    std::optional<double> mean_sah;
    std::optional<double> mean_memory_bytes;
    double mean_frame_ms() const noexcept { return mean_build_ms + mean_trace_ms; }
};

inline Summary summarize(const std::vector<FrameRecord>& recs, std::size_t rays_per_frame) {
    Summary s;
    s.frames = recs.size();
    if (recs.empty()) return s;
    double sah = 0, mem = 0;
    bool all_sah = true, all_mem = true;
    for (const FrameRecord& r : recs) {
        s.total_build_ms += r.build_ms;
        s.total_trace_ms += r.trace_ms;
        if (r.sah) sah += *r.sah; else all_sah = false;
        if (r.memory_bytes) mem += double(*r.memory_bytes); else all_mem = false;
    }
    const double n = double(recs.size());
    s.mean_build_ms = s.total_build_ms / n;
    s.mean_trace_ms = s.total_trace_ms / n;
    const double total_s = (s.total_build_ms + s.total_trace_ms) / 1000.0;
    s.fps = total_s > 0 ? n / total_s : std::numeric_limits<double>::infinity();
    s.mrays_per_s = s.total_trace_ms > 0 ? double(rays_per_frame) * n / (s.total_trace_ms / 1000.0) / 1e6 : 0;
    if (all_sah) s.mean_sah = sah / n;
    if (all_mem) s.mean_memory_bytes = mem / n;
    return s;
}

/// Sum of the records' effects; none when no record has them (--effects primary).
inline std::optional<EffectsRecord> sum_effects(const std::vector<FrameRecord>& recs) {
    std::optional<EffectsRecord> s;
    for (const FrameRecord& r : recs) {
        if (!r.effects) continue;
        if (!s) s.emplace();
        for (std::size_t k = 0; k < 4; ++k) {
            s->rays[k] += r.effects->rays[k];
            s->ms[k] += r.effects->ms[k];
        }
        s->shade_ms += r.effects->shade_ms;
        s->depth = std::max(s->depth, r.effects->depth);
    }
    return s;
}

/// All frames of one scene x builder x resolution (every repetition).
struct GroupResult {
    std::string scene;
    std::string builder;
    Resolution res;
    std::vector<FrameRecord> records;
    Summary summary() const { return summarize(records, res.rays()); }
};

/// What the study knows about a scene it ran.
struct SceneSummary {
    std::string name;                 ///< built-in name or the scene's own name
    std::string spec;                 ///< as given on the command line
    std::string kind;                 ///< builtin, mesh, frames, bart
    std::string format;               ///< builtin, ply, obj, aff, mixed
    std::string motion;
    bool topology_changes = false;
    double scale = 1;                 ///< built-in scenes: triangle-count scale (1 = the thesis's size)
    std::size_t frames_total = 0;     ///< frames in the scene
    std::vector<std::uint32_t> frames_used;
    std::size_t triangles_min = 0, triangles_max = 0;   ///< over the frames used
    std::size_t materials = 0, lights = 0;
    bool full_size() const noexcept { return kind != "builtin" || scale == 1.0; }
};

/// A rendered frame written as PNG.
struct ImageRecord {
    std::string scene;
    std::uint32_t frame = 0;
    std::string builder;
    Resolution res;
    std::string file;                 ///< relative to the output directory
    std::size_t hit_pixels = 0;
};

/// A scene x builder combination that was not run, and why.
struct Skip {
    std::string scene, builder, reason;
};

/// One sweep setting on one scene: its frames plus the hit differences against the reference setting.
struct SweepResult {
    std::string scene;
    std::string group;                ///< the knob, e.g. "ploc radius"
    std::string setting;              ///< canonical builder spec, e.g. "ploc:r=16"
    std::string value;                ///< the knob's value as shown in tables ("r=16")
    bool ordered = true;              ///< the values form a scale (radius, budget) rather than alternatives
    Resolution res;
    std::vector<FrameRecord> records;
    std::size_t compared_pixels = 0;  ///< pixels compared with the reference
    std::size_t changed = 0;          ///< both hit, different triangle
    std::size_t lost = 0;             ///< reference hit, this setting missed
    std::size_t gained = 0;           ///< reference missed, this setting hit
    Summary summary() const { return summarize(records, res.rays()); }
};

/// Host description stored with every result.
struct MachineInfo {
    std::string cpu;
    unsigned cores = 0;
    double memory_gib = 0;
    std::string compiler;
    std::string date;                 ///< ISO 8601, UTC
    std::string embree;               ///< version, or empty when built without Embree
};

} // namespace dynbvh::study

namespace dynbvh::study {

/// `name` with every character outside [A-Za-z0-9._-] replaced by '_' (for file names).
inline std::string safe_file_name(const std::string& name) {
    std::string s = name;
    for (auto& c : s)
        if (!((c >= 'a' && c <= 'z') || (c >= 'A' && c <= 'Z') || (c >= '0' && c <= '9') || c == '.' || c == '-' || c == '_')) c = '_';
    return s.empty() ? "scene" : s;
}

} // namespace dynbvh::study
