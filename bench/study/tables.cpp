#include "tables.hpp"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <limits>

#include "crossover.hpp"
#include "thesis.hpp"

namespace dynbvh::study {

std::string fmt(double x) {
    if (!std::isfinite(x)) return "-";
    char buf[64];
    const double a = std::abs(x);
    if (a >= 1000) std::snprintf(buf, sizeof buf, "%.0f", x);
    else if (a >= 100) std::snprintf(buf, sizeof buf, "%.1f", x);
    else if (a >= 10) std::snprintf(buf, sizeof buf, "%.2f", x);
    else if (a >= 1) std::snprintf(buf, sizeof buf, "%.3f", x);
    else if (a == 0) std::snprintf(buf, sizeof buf, "0");
    else std::snprintf(buf, sizeof buf, "%.3g", x);
    return buf;
}

std::string render_text(const Table& t) {
    std::vector<std::size_t> w(t.header.size(), 0);
    for (std::size_t c = 0; c < t.header.size(); ++c) w[c] = t.header[c].size();
    for (const auto& r : t.rows)
        for (std::size_t c = 0; c < r.size() && c < w.size(); ++c) w[c] = std::max(w[c], r[c].size());
    std::string o = t.title + "\n";
    auto line = [&](const std::vector<std::string>& cells) {
        std::string l;
        for (std::size_t c = 0; c < w.size(); ++c) {
            const std::string s = c < cells.size() ? cells[c] : "";
            const std::size_t pad = w[c] - s.size();
            if (c < 2) l += s + std::string(pad, ' ');   // label columns left-aligned
            else l += std::string(pad, ' ') + s;
            l += c + 1 < w.size() ? "  " : "";
        }
        while (!l.empty() && l.back() == ' ') l.pop_back();
        return l + "\n";
    };
    o += line(t.header);
    std::size_t total = 0;
    for (auto x : w) total += x + 2;
    o += std::string(total > 2 ? total - 2 : 0, '-') + "\n";
    for (const auto& r : t.rows) o += line(r);
    for (const auto& n : t.notes) o += "  " + n + "\n";
    return o;
}

namespace {
std::string md_escape(const std::string& s) {
    std::string o;
    for (char c : s) {
        if (c == '*' || c == '|' || c == '_') o += '\\';
        o += c;
    }
    return o;
}
} // namespace

std::string render_markdown(const Table& t) {
    std::string o = "**" + md_escape(t.title) + "**\n\n|";
    for (const auto& h : t.header) o += " " + md_escape(h) + " |";
    o += "\n|";
    for (std::size_t c = 0; c < t.header.size(); ++c) o += c < 2 ? " --- |" : " ---: |";
    o += "\n";
    for (const auto& r : t.rows) {
        o += "|";
        for (std::size_t c = 0; c < t.header.size(); ++c) o += " " + md_escape(c < r.size() ? r[c] : std::string()) + " |";
        o += "\n";
    }
    if (!t.notes.empty()) {
        o += "\n";
        for (const auto& n : t.notes) o += md_escape(n) + "\n\n";
    }
    return o + "\n";
}

const GroupResult* find_group(const StudyResults& r, const std::string& scene, const std::string& builder, Resolution res) {
    for (const auto& g : r.groups)
        if (g.scene == scene && g.builder == builder && g.res == res) return &g;
    return nullptr;
}

std::vector<FrameRecord> records_all_res(const StudyResults& r, const std::string& scene, const std::string& builder) {
    std::vector<FrameRecord> v;
    for (const auto& g : r.groups)
        if (g.scene == scene && g.builder == builder) v.insert(v.end(), g.records.begin(), g.records.end());
    return v;
}

Table scenes_table(const std::vector<SceneSummary>& scenes) {
    Table t;
    t.title = "Scenes";
    t.header = {"scene", "kind", "triangles", "frames used", "motion", "topology", "thesis scene"};
    for (const auto& s : scenes) {
        std::string tris = std::to_string(s.triangles_min);
        if (s.triangles_max != s.triangles_min) tris += " to " + std::to_string(s.triangles_max);
        std::string kind = s.kind == "builtin" ? "built-in, scale " + fmt(s.scale) : s.kind + " (" + s.format + ")";
        const int col = thesis::scene_column(s.name);
        t.rows.push_back({s.name, kind, tris, std::to_string(s.frames_used.size()) + " of " + std::to_string(s.frames_total), s.motion,
                          s.topology_changes ? "changes" : "kept", col >= 0 ? thesis::scene_name(col) : "-"});
    }
    return t;
}

namespace {

std::vector<std::string> scene_headers(const StudyResults& r, bool& any_reduced) {
    std::vector<std::string> h;
    any_reduced = false;
    for (const auto& s : r.scenes) {
        std::string name = s.name;
        if (!s.full_size()) {
            name += "*";
            any_reduced = true;
        }
        h.push_back(name);
    }
    return h;
}

std::string cell(double ours, std::optional<double> theirs) {
    if (!std::isfinite(ours)) return "-";
    std::string s = fmt(ours);
    if (theirs) s += " (" + fmt(*theirs) + ")";
    return s;
}

void add_notes(Table& t, const StudyResults& r, bool reduced, bool has_thesis) {
    if (has_thesis)
        t.notes.push_back("(x) = the thesis's figure for the corresponding UNC scene (Cloth-ball, N-body, Dragon, Lion; "
                          "i7-9750H, 12 threads). Ours: " + std::to_string(r.threads) + " threads, " + r.backend + ".");
    if (reduced)
        t.notes.push_back("* built-in scene at reduced scale (" + fmt(r.options.scale) +
                          "): fewer triangles than the thesis's scene, so the figures are not comparable with it.");
}

/// Rows = resolution x builder, columns = scenes.
Table per_res_table(const StudyResults& r, const std::string& title, std::optional<thesis::Metric> metric,
                    double (*pick)(const Summary&), bool& has_thesis) {
    Table t;
    t.title = title;
    bool reduced = false;
    t.header = {"resolution", "builder"};
    for (auto& h : scene_headers(r, reduced)) t.header.push_back(h);
    has_thesis = false;
    for (const auto& res : r.options.resolutions) {
        bool first = true;
        for (const auto& b : r.builders) {
            std::vector<std::string> row{first ? res.str() : "", b};
            bool any = false;
            for (const auto& s : r.scenes) {
                const GroupResult* g = find_group(r, s.name, b, res);
                if (!g || g->records.empty()) {
                    row.push_back("-");
                    continue;
                }
                any = true;
                const auto th = metric ? thesis::value(*metric, b, s.name, res) : std::nullopt;
                if (th) has_thesis = true;
                row.push_back(cell(pick(g->summary()), th));
            }
            if (any) {
                t.rows.push_back(row);
                first = false;
            }
        }
    }
    add_notes(t, r, reduced, has_thesis);
    return t;
}

/// Rows = builder, columns = scenes, over every resolution's records.
Table all_res_table(const StudyResults& r, const std::string& title, thesis::Metric metric, bool sah, bool memory) {
    Table t;
    t.title = title;
    bool reduced = false;
    t.header = {"builder", ""};
    for (auto& h : scene_headers(r, reduced)) t.header.push_back(h);
    bool has_thesis = false;
    for (const auto& b : r.builders) {
        std::vector<std::string> row{b, ""};
        bool any = false;
        for (const auto& s : r.scenes) {
            const auto recs = records_all_res(r, s.name, b);
            if (recs.empty()) {
                row.push_back("-");
                continue;
            }
            any = true;
            const Summary sm = summarize(recs, 0);
            const auto th = thesis::value(metric, b, s.name, r.options.resolutions.front());
            if (th && !memory) has_thesis = true;
            if (sah) row.push_back(sm.mean_sah ? cell(*sm.mean_sah, th) : "-");
            else if (memory) row.push_back(sm.mean_memory_bytes ? fmt(*sm.mean_memory_bytes / (1024.0 * 1024.0)) : "-");
            else row.push_back(cell(sm.mean_build_ms, th));
        }
        if (any) t.rows.push_back(row);
    }
    add_notes(t, r, reduced, has_thesis);
    return t;
}

} // namespace

std::vector<Table> study_tables(const StudyResults& r) {
    std::vector<Table> v;
    bool th = false;
    v.push_back(per_res_table(r, "Table 5.2  FPS = frames / (total build + total trace)", thesis::Metric::fps,
                              [](const Summary& s) { return s.fps; }, th));
    v.push_back(all_res_table(r, "Table 5.3  Mean build time per frame, ms", thesis::Metric::build_ms, false, false));
    v.push_back(per_res_table(r, "Table 5.4  Mean trace time per frame, ms (one primary ray per pixel)", thesis::Metric::trace_ms,
                              [](const Summary& s) { return s.mean_trace_ms; }, th));
    v.push_back(all_res_table(r, "Table 5.5  Mean SAH cost per frame (Ct = 3, Ci = 2)", thesis::Metric::sah, true, false));
    v.push_back(per_res_table(r, "Trace speed, Mrays/s", std::nullopt, [](const Summary& s) { return s.mrays_per_s; }, th));
    v.push_back(all_res_table(r, "Tree memory, MiB (nodes + references)", thesis::Metric::sah, false, true));
    return v;
}

std::vector<Table> effects_tables(const StudyResults& r) {
    std::vector<Table> v;
    for (const auto& s : r.scenes) {
        Table t;
        t.title = "Effects on " + s.name + ": mean per frame, rays and tracing time per kind (--effects auto, depth " +
                  std::to_string(r.options.effects_depth) + ")";
        t.header = {"resolution", "builder"};
        for (const char* k : effect_kind_names) t.header.push_back(std::string(k) + " rays");
        for (const char* k : effect_kind_names) t.header.push_back(std::string(k) + " ms");
        t.header.push_back("shade ms");
        t.header.push_back("secondary ms vs best");
        for (const auto& res : r.options.resolutions) {
            // The fastest builder's secondary (shadow + reflection + refraction) time at this resolution.
            double best = std::numeric_limits<double>::infinity();
            for (const auto& b : r.builders)
                if (const GroupResult* g = find_group(r, s.name, b, res)) {
                    if (const auto e = sum_effects(g->records)) best = std::min(best, e->ms[1] + e->ms[2] + e->ms[3]);
                }
            bool first = true;
            for (const auto& b : r.builders) {
                const GroupResult* g = find_group(r, s.name, b, res);
                if (!g || g->records.empty()) continue;
                const auto e = sum_effects(g->records);
                if (!e) continue;
                const double n = double(g->records.size());
                std::vector<std::string> row{first ? res.str() : "", b};
                first = false;
                for (std::size_t k = 0; k < 4; ++k) row.push_back(format_rays(double(e->rays[k]) / n));
                for (std::size_t k = 0; k < 4; ++k) row.push_back(e->rays[k] ? fmt(e->ms[k] / n) : "-");
                row.push_back(fmt(e->shade_ms / n));
                const double sec = e->ms[1] + e->ms[2] + e->ms[3];
                char buf[32];
                std::snprintf(buf, sizeof buf, "%.2fx", sec / best);
                row.push_back(best > 0 && std::isfinite(best) ? std::string(buf) : "-");
                t.rows.push_back(row);
            }
        }
        if (t.rows.empty()) continue;
        t.notes.push_back("Whitted renderer (bench/render/whitted.hpp) after the primary trace, closest-hit / any-hit queries "
                          "through the same structure (primary rays in packets of 16 with --rays packet, the default; shadow, "
                          "reflection and refraction rays one at a time); each kind traced in its own passes and timed apart. Shadow rays only "
                          "towards the scene's lights, reflection rays only from specular or transparent materials, refraction rays "
                          "only from transparent ones. shade = shading, ray generation and queues (not tracing).");
        v.push_back(t);
    }
    return v;
}

std::vector<Table> sweep_tables(const StudyResults& r) {
    std::vector<Table> v;
    for (const auto& s : r.sweep_scenes) {
        Table t;
        const Resolution res = r.sweep.empty() ? Resolution{} : r.sweep.front().res;
        t.title = "What accuracy costs in time: " + s.name + (s.full_size() ? "" : " (scale " + fmt(s.scale) + ")") + ", " +
                  std::to_string(s.frames_used.size()) + " frames at " + res.str() + "; hits compared with " + r.sweep_reference;
        t.header = {"knob", "value", "builder spec", "build ms", "trace ms", "frame ms", "Mrays/s", "SAH", "MiB", "hits changed", "lost", "gained"};
        std::string last_group;
        for (const auto& x : r.sweep) {
            if (x.scene != s.name) continue;
            const Summary sm = x.summary();
            auto pct = [&](std::size_t n) {
                if (x.compared_pixels == 0) return std::string("-");
                char buf[32];
                std::snprintf(buf, sizeof buf, "%.4f%%", 100.0 * double(n) / double(x.compared_pixels));
                return std::string(buf);
            };
            t.rows.push_back({x.group == last_group ? "" : x.group, x.value, x.setting, fmt(sm.mean_build_ms), fmt(sm.mean_trace_ms),
                              fmt(sm.mean_frame_ms()), fmt(sm.mrays_per_s), sm.mean_sah ? fmt(*sm.mean_sah) : "-",
                              sm.mean_memory_bytes ? fmt(*sm.mean_memory_bytes / (1024.0 * 1024.0)) : "-", pct(x.changed),
                              pct(x.lost), pct(x.gained)});
            last_group = x.group;
        }
        t.notes.push_back("changed: both hit, another triangle; lost: the reference hit, this setting missed; gained: the opposite "
                          "(percent of pixels x frames).");
        v.push_back(t);
    }
    return v;
}

} // namespace dynbvh::study
