#include "output.hpp"

#include <charconv>
#include <cmath>
#include <fstream>
#include <optional>
#include <stdexcept>

#include <nlohmann/json.hpp>

namespace dynbvh::study {

namespace {

// Fields stay in the order written (study.json is read by people too).
using Json = nlohmann::ordered_json;

template <class T>
Json opt(const std::optional<T>& x) {
    return x ? Json(*x) : Json(nullptr);
}

/// {"rays": {"primary": n, ...}, "ms": {...}, "shade_ms": x, "depth": d}, every figure divided by `n`.
Json effects_json(const EffectsRecord& e, double n) {
    Json rays = Json::object(), ms = Json::object();
    for (std::size_t k = 0; k < 4; ++k) {
        rays[effect_kind_names[k]] = double(e.rays[k]) / n;
        ms[effect_kind_names[k]] = e.ms[k] / n;
    }
    return {{"rays", rays}, {"ms", ms}, {"shade_ms", e.shade_ms / n}, {"depth", e.depth}};
}

Json records_json(const std::vector<FrameRecord>& recs) {
    Json a = Json::array();
    for (const auto& f : recs) {
        Json j = {{"rep", f.rep},         {"frame", f.frame},   {"triangles", f.triangles},
                  {"build_ms", f.build_ms}, {"trace_ms", f.trace_ms}, {"sah", opt(f.sah)},
                  {"memory_bytes", opt(f.memory_bytes)}, {"hits", f.hits}};
        if (f.effects) j["effects"] = effects_json(*f.effects, 1);
        if (f.strategy) {
            j["decision"] = f.strategy->decision;
            j["reason"] = f.strategy->reason;
            j["sah_before"] = opt(f.strategy->sah_before);
            j["sah_after"] = f.strategy->sah_after;
            j["sah_rebuilt"] = f.strategy->sah_rebuilt;
            j["rebuild_started"] = f.strategy->rebuild_started;
            j["rule"] = f.strategy->rule;
            j["loss_ms"] = f.strategy->loss_ms;
            j["rebuild_cost_ms"] = f.strategy->rebuild_cost_ms;
            j["trust"] = f.strategy->trust;
            j["elasticity"] = f.strategy->elasticity;
        }
        a.push_back(std::move(j));
    }
    return a;
}

/// Strategies (auto): {"threshold", "refit", "rebuild", "swap"} counted over `recs`; null for per-frame builders.
Json strategy_json(const std::vector<FrameRecord>& recs) {
    if (recs.empty() || !recs.front().strategy) return nullptr;
    std::size_t refit = 0, rebuild = 0, swap = 0;
    for (const auto& f : recs) {
        if (!f.strategy) continue;
        refit += f.strategy->decision == "refit";
        rebuild += f.strategy->decision == "rebuild";
        swap += f.strategy->decision == "swap";
    }
    return {{"rule", recs.front().strategy->rule}, {"threshold", recs.front().strategy->threshold}, {"refit", refit}, {"rebuild", rebuild}, {"swap", swap}};
}

void add_summary(Json& j, const Summary& s) {
    j["frames"] = s.frames;
    j["total_build_ms"] = s.total_build_ms;
    j["total_trace_ms"] = s.total_trace_ms;
    j["mean_build_ms"] = s.mean_build_ms;
    j["mean_trace_ms"] = s.mean_trace_ms;
    j["mrays_per_s"] = s.mrays_per_s;
    j["fps"] = s.fps;
    j["mean_sah"] = opt(s.mean_sah);
    j["mean_memory_bytes"] = opt(s.mean_memory_bytes);
}

Json scene_json(const SceneSummary& s) {
    return {{"name", s.name},
            {"spec", s.spec},
            {"kind", s.kind},
            {"format", s.format},
            {"scale", s.scale},
            {"motion", s.motion},
            {"topology_changes", s.topology_changes},
            {"frames_total", s.frames_total},
            {"frames_used", s.frames_used},
            {"triangles_min", s.triangles_min},
            {"triangles_max", s.triangles_max},
            {"materials", s.materials},
            {"lights", s.lights}};
}

} // namespace

std::string json_text(const nlohmann::ordered_json& j) {
    // NaN and inf come out as null; bytes that are not UTF-8 (a path, a CPU name) as U+FFFD.
    return j.dump(1, ' ', false, nlohmann::ordered_json::error_handler_t::replace) + "\n";
}

std::string study_json(const StudyResults& r) {
    Json j;
    j["format"] = "dynbvh-study 1";
    j["machine"] = {{"cpu", r.machine.cpu}, {"cores", r.machine.cores}, {"memory_gib", r.machine.memory_gib}};
    j["compiler"] = r.machine.compiler;
    j["backend"] = r.backend;
    j["threads"] = r.threads;
    j["date"] = r.machine.date;
    j["embree"] = r.machine.embree.empty() ? Json(nullptr) : Json(r.machine.embree);
    j["wall_s"] = r.wall_s;
    const Options& o = r.options;
    Json res = Json::array();
    for (const auto& x : o.resolutions) res.push_back(x.str());
    j["options"] = {{"command_line", o.command_line},
                    {"resolutions", res},
                    {"reps", o.reps},
                    {"frames", o.frames},
                    {"frame_step", o.frame_step},
                    {"scale", o.scale},
                    {"seed", o.seed},
                    {"quick", o.quick},
                    {"full", o.full},
                    {"sweep", o.sweep},
                    {"warmup", o.warmup},
                    {"effects", o.effects ? "auto" : "primary"},
                    {"rays", o.packets ? "packet" : "single"},
                    {"effects_depth", o.effects_depth}};
    j["builders"] = r.builders;
    j["scenes"] = Json::array();
    for (const auto& s : r.scenes) j["scenes"].push_back(scene_json(s));
    j["results"] = Json::array();
    for (const auto& g : r.groups) {
        Json x = {{"scene", g.scene},   {"builder", g.builder},          {"width", g.res.width},
                  {"height", g.res.height}, {"rays_per_frame", g.res.rays()}, {"reps", o.reps}};
        add_summary(x, g.summary());
        // means per frame of the records' effects, or null
        const auto e = sum_effects(g.records);
        x["effects"] = e && !g.records.empty() ? effects_json(*e, double(g.records.size())) : Json(nullptr);
        x["strategy"] = strategy_json(g.records);
        x["per_frame"] = records_json(g.records);
        j["results"].push_back(std::move(x));
    }
    j["images"] = Json::array();
    for (const auto& im : r.images)
        j["images"].push_back({{"scene", im.scene},         {"frame", im.frame}, {"builder", im.builder},
                               {"width", im.res.width},     {"height", im.res.height}, {"file", im.file},
                               {"hit_pixels", im.hit_pixels}});
    j["skipped"] = Json::array();
    for (const auto& s : r.skipped) j["skipped"].push_back({{"scene", s.scene}, {"builder", s.builder}, {"reason", s.reason}});
    j["notices"] = r.notices;
    if (r.sweep.empty()) {
        j["sweep"] = nullptr;
    } else {
        Json sw;
        sw["reference"] = r.sweep_reference;
        sw["scenes"] = Json::array();
        for (const auto& s : r.sweep_scenes) sw["scenes"].push_back(scene_json(s));
        sw["settings"] = Json::array();
        for (const auto& x : r.sweep) {
            Json y = {{"scene", x.scene}, {"group", x.group},          {"value", x.value},
                      {"setting", x.setting}, {"width", x.res.width},  {"height", x.res.height},
                      {"rays_per_frame", x.res.rays()}};
            add_summary(y, x.summary());
            y["compared_pixels"] = x.compared_pixels;
            y["hits_changed"] = x.changed;
            y["hits_lost"] = x.lost;
            y["hits_gained"] = x.gained;
            y["per_frame"] = records_json(x.records);
            sw["settings"].push_back(std::move(y));
        }
        j["sweep"] = std::move(sw);
    }
    return json_text(j);
}

namespace {
/// Shortest text that reads back as `x`; empty for NaN/inf.
std::string csv_number(double x) {
    if (!std::isfinite(x)) return "";
    char buf[64];
    const auto r = std::to_chars(buf, buf + sizeof buf, x);
    return std::string(buf, r.ptr);
}

std::string csv_field(const std::string& s) {
    if (s.find_first_of(",\"\n") == std::string::npos) return s;
    std::string o = "\"";
    for (char c : s) o += c == '"' ? std::string("\"\"") : std::string(1, c);
    return o + "\"";
}
} // namespace

std::string study_csv(const StudyResults& r) {
    std::string o = "kind,scene,builder,group,width,height,rep,frame,triangles,build_ms,trace_ms,sah,memory_bytes,hits,"
                    "rays_primary,rays_shadow,rays_reflection,rays_refraction,ms_primary,ms_shadow,ms_reflection,ms_refraction,"
                    "ms_shade,decision,reason,sah_before,sah_after,sah_rebuilt,loss_ms,rebuild_cost_ms\n";
    auto row = [&](const char* kind, const std::string& scene, const std::string& builder, const std::string& group, Resolution res,
                   const FrameRecord& f) {
        o += std::string(kind) + "," + csv_field(scene) + "," + csv_field(builder) + "," + csv_field(group) + "," +
             std::to_string(res.width) + "," + std::to_string(res.height) + "," + std::to_string(f.rep) + "," + std::to_string(f.frame) +
             "," + std::to_string(f.triangles) + "," + csv_number(f.build_ms) + "," + csv_number(f.trace_ms) + "," +
             (f.sah ? csv_number(*f.sah) : "") + "," + (f.memory_bytes ? std::to_string(*f.memory_bytes) : "") + "," +
             std::to_string(f.hits);
        for (std::size_t k = 0; k < 4; ++k) o += "," + (f.effects ? std::to_string(f.effects->rays[k]) : std::string());
        for (std::size_t k = 0; k < 4; ++k) o += "," + (f.effects ? csv_number(f.effects->ms[k]) : std::string());
        o += "," + (f.effects ? csv_number(f.effects->shade_ms) : std::string());
        if (f.strategy)
            o += "," + f.strategy->decision + "," + f.strategy->reason + "," +
                 (f.strategy->sah_before ? csv_number(*f.strategy->sah_before) : std::string()) + "," +
                 csv_number(f.strategy->sah_after) + "," + csv_number(f.strategy->sah_rebuilt) + "," +
                 csv_number(f.strategy->loss_ms) + "," + csv_number(f.strategy->rebuild_cost_ms) + "\n";
        else
            o += ",,,,,,,\n";
    };
    for (const auto& g : r.groups)
        for (const auto& f : g.records) row("study", g.scene, g.builder, "", g.res, f);
    for (const auto& x : r.sweep)
        for (const auto& f : x.records) row("sweep", x.scene, x.setting, x.group, x.res, f);
    return o;
}

void write_text(const std::string& path, const std::string& text) {
    std::ofstream out(path, std::ios::binary | std::ios::trunc);
    if (!out) throw std::runtime_error("cannot write " + path);
    out.write(text.data(), std::streamsize(text.size()));
    if (!out) throw std::runtime_error("cannot write " + path);
}

} // namespace dynbvh::study
