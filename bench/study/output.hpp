// study.json and study.csv: every per-frame measurement with the machine, compiler, backend,
// thread count and date. The JSON's layout is documented in study_json's comment.
#pragma once

#include <string>

#include <nlohmann/json_fwd.hpp>

#include "runner.hpp"

namespace dynbvh::study {

/// The whole result as JSON:
/// { "format": "dynbvh-study 1", "machine": {...}, "compiler", "backend", "threads", "date", "embree",
///   "options": {...}, "scenes": [...], "builders": [...],
///   "results": [ { "scene", "builder", "width", "height", "rays_per_frame", "frames", "reps",
///                  "total_build_ms", "total_trace_ms", "mean_build_ms", "mean_trace_ms", "mrays_per_s",
///                  "fps", "mean_sah", "mean_memory_bytes", "effects", "strategy",
///                  "per_frame": [ {"rep", "frame", "triangles", "build_ms", "trace_ms", "sah", "memory_bytes", "hits",
///                                  ["effects"], ["decision", "reason", "sah_before", "sah_after", "sah_rebuilt",
///                                  "rebuild_started"]} ] } ],
///   "images": [...], "skipped": [...], "notices": [...], "sweep": {...} }
/// fps = per_frame count / (sum of build_ms + trace_ms) * 1000; null where a figure does not exist (Embree SAH).
/// "effects" (--effects auto; null or absent otherwise): {"rays": {"primary", "shadow", "reflection", "refraction"},
/// "ms": {same kinds: tracing time}, "shade_ms", "depth"}; per frame, and in a result the mean per frame.
/// trace_ms stays the study's own primary trace (the effects render runs after it, timed apart).
/// Strategies (auto) only: per frame "decision" (refit, rebuild, swap), "reason" (none, first_frame, topology,
/// finiteness, sah_growth, rebuild_ready), "sah_before" (the previous tree refitted to this frame, null when there
/// was none), "sah_after" (the serving tree, = "sah"), "sah_rebuilt" (its SAH right after its build: a refit
/// rebuilds when sah_before > threshold x the previous frame's sah_rebuilt), "rebuild_started" (async); per result
/// "strategy": {"threshold", "refit", "rebuild", "swap"} (decision counts), null for per-frame builders.
/// two-level: "sah" null (no one tree), "memory_bytes" = every object tree plus the top-level tree.
std::string study_json(const StudyResults& r);

/// One CSV row per measured frame (study and sweep): kind,scene,builder,group,width,height,rep,frame,
/// triangles,build_ms,trace_ms,sah,memory_bytes,hits, then rays and ms per kind (primary, shadow, reflection,
/// refraction) and ms_shade with --effects auto (empty otherwise), then decision,reason,sah_before,sah_after,
/// sah_rebuilt for strategies (auto; empty otherwise).
std::string study_csv(const StudyResults& r);

/// `j` as pretty-printed text (one space per level, fields in insertion order, NaN/inf as null,
/// invalid UTF-8 replaced), ending in a newline.
std::string json_text(const nlohmann::ordered_json& j);

/// Writes `text` to `path` (replacing it); throws std::runtime_error naming the file on failure.
void write_text(const std::string& path, const std::string& text);

} // namespace dynbvh::study
