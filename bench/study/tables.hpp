// Tables laid out like the thesis's Tables 5.2 (FPS), 5.3 (build ms), 5.4 (trace ms) and 5.5 (SAH),
// with the thesis's figures beside ours, plus Mrays/s, tree memory, the scenes and the sweep;
// rendered as aligned text (terminal) or Markdown (report).
#pragma once

#include <string>
#include <vector>

#include "runner.hpp"

namespace dynbvh::study {

struct Table {
    std::string title;
    std::vector<std::string> header;
    std::vector<std::vector<std::string>> rows;
    std::vector<std::string> notes;
};

std::string render_text(const Table& t);
std::string render_markdown(const Table& t);

/// Number with about 3-4 significant digits ("1234", "12.3", "0.123").
std::string fmt(double x);

/// The scenes run (triangles, frames, motion, topology).
Table scenes_table(const std::vector<SceneSummary>& scenes);
/// Tables 5.2-5.5 plus Mrays/s and memory.
std::vector<Table> study_tables(const StudyResults& r);
/// --effects auto: one table per scene with effects: per resolution and builder, the mean rays per frame
/// of each kind, the tracing time of each kind, the shading time, and the secondary rays' time relative
/// to the fastest builder. Empty when nothing was rendered with effects.
std::vector<Table> effects_tables(const StudyResults& r);
/// One table per sweep scene: every setting's build, trace, SAH and hit differences.
std::vector<Table> sweep_tables(const StudyResults& r);

/// Records of every resolution of scene x builder (build time and SAH do not depend on resolution).
std::vector<FrameRecord> records_all_res(const StudyResults& r, const std::string& scene, const std::string& builder);
/// The group of scene x builder x resolution, or null.
const GroupResult* find_group(const StudyResults& r, const std::string& scene, const std::string& builder, Resolution res);

} // namespace dynbvh::study
