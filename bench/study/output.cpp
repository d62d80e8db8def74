#include "output.hpp"

#include <fstream>
#include <stdexcept>

#include "json.hpp"

namespace dynbvh::study {

namespace {

/// {"rays": {"primary": n, ...}, "ms": {...}, "shade_ms": x, "depth": d}, every figure divided by `n`.
void write_effects(JsonWriter& j, const EffectsRecord& e, double n) {
    j.begin_object(true);
    j.key("rays");
    j.begin_object(true);
    for (std::size_t k = 0; k < 4; ++k) j.kv(effect_kind_names[k], double(e.rays[k]) / n);
    j.end_object();
    j.key("ms");
    j.begin_object(true);
    for (std::size_t k = 0; k < 4; ++k) j.kv(effect_kind_names[k], e.ms[k] / n);
    j.end_object();
    j.kv("shade_ms", e.shade_ms / n);
    j.kv("depth", e.depth);
    j.end_object();
}

void write_records(JsonWriter& j, const std::vector<FrameRecord>& recs) {
    j.key("per_frame");
    j.begin_array();
    for (const auto& f : recs) {
        j.begin_object(true);
        j.kv("rep", f.rep);
        j.kv("frame", f.frame);
        j.kv("triangles", f.triangles);
        j.kv("build_ms", f.build_ms);
        j.kv("trace_ms", f.trace_ms);
        j.kv("sah", f.sah);
        j.kv("memory_bytes", f.memory_bytes);
        j.kv("hits", f.hits);
        if (f.effects) {
            j.key("effects");
            write_effects(j, *f.effects, 1);
        }
        j.end_object();
    }
    j.end_array();
}

void write_summary(JsonWriter& j, const Summary& s) {
    j.kv("frames", s.frames);
    j.kv("total_build_ms", s.total_build_ms);
    j.kv("total_trace_ms", s.total_trace_ms);
    j.kv("mean_build_ms", s.mean_build_ms);
    j.kv("mean_trace_ms", s.mean_trace_ms);
    j.kv("mrays_per_s", s.mrays_per_s);
    j.kv("fps", s.fps);
    j.kv("mean_sah", s.mean_sah);
    j.kv("mean_memory_bytes", s.mean_memory_bytes);
}

void write_scene(JsonWriter& j, const SceneSummary& s) {
    j.begin_object();
    j.kv("name", s.name);
    j.kv("spec", s.spec);
    j.kv("kind", s.kind);
    j.kv("format", s.format);
    j.kv("scale", s.scale);
    j.kv("motion", s.motion);
    j.kv("topology_changes", s.topology_changes);
    j.kv("frames_total", s.frames_total);
    j.key("frames_used");
    j.begin_array(true);
    for (auto f : s.frames_used) j.value(f);
    j.end_array();
    j.kv("triangles_min", s.triangles_min);
    j.kv("triangles_max", s.triangles_max);
    j.kv("materials", s.materials);
    j.kv("lights", s.lights);
    j.end_object();
}

} // namespace

std::string study_json(const StudyResults& r) {
    JsonWriter j(true);
    j.begin_object();
    j.kv("format", "dynbvh-study 1");
    j.key("machine");
    j.begin_object();
    j.kv("cpu", r.machine.cpu);
    j.kv("cores", r.machine.cores);
    j.kv("memory_gib", r.machine.memory_gib);
    j.end_object();
    j.kv("compiler", r.machine.compiler);
    j.kv("backend", r.backend);
    j.kv("threads", r.threads);
    j.kv("date", r.machine.date);
    j.key("embree");
    if (r.machine.embree.empty()) j.null();
    else j.value(r.machine.embree);
    j.kv("wall_s", r.wall_s);
    const Options& o = r.options;
    j.key("options");
    j.begin_object();
    j.kv("command_line", o.command_line);
    j.key("resolutions");
    j.begin_array(true);
    for (const auto& x : o.resolutions) j.value(x.str());
    j.end_array();
    j.kv("reps", o.reps);
    j.kv("frames", o.frames);
    j.kv("frame_step", o.frame_step);
    j.kv("scale", o.scale);
    j.kv("seed", static_cast<unsigned long long>(o.seed));
    j.kv("quick", o.quick);
    j.kv("full", o.full);
    j.kv("sweep", o.sweep);
    j.kv("warmup", o.warmup);
    j.kv("effects", o.effects ? "auto" : "primary");
    j.kv("effects_depth", o.effects_depth);
    j.end_object();
    j.key("builders");
    j.begin_array(true);
    for (const auto& b : r.builders) j.value(b);
    j.end_array();
    j.key("scenes");
    j.begin_array();
    for (const auto& s : r.scenes) write_scene(j, s);
    j.end_array();
    j.key("results");
    j.begin_array();
    for (const auto& g : r.groups) {
        j.begin_object();
        j.kv("scene", g.scene);
        j.kv("builder", g.builder);
        j.kv("width", g.res.width);
        j.kv("height", g.res.height);
        j.kv("rays_per_frame", g.res.rays());
        j.kv("reps", o.reps);
        write_summary(j, g.summary());
        j.key("effects");   // means per frame of the records' effects, or null
        if (const auto e = sum_effects(g.records); e && !g.records.empty()) write_effects(j, *e, double(g.records.size()));
        else j.null();
        write_records(j, g.records);
        j.end_object();
    }
    j.end_array();
    j.key("images");
    j.begin_array();
    for (const auto& im : r.images) {
        j.begin_object(true);
        j.kv("scene", im.scene);
        j.kv("frame", im.frame);
        j.kv("builder", im.builder);
        j.kv("width", im.res.width);
        j.kv("height", im.res.height);
        j.kv("file", im.file);
        j.kv("hit_pixels", im.hit_pixels);
        j.end_object();
    }
    j.end_array();
    j.key("skipped");
    j.begin_array();
    for (const auto& s : r.skipped) {
        j.begin_object(true);
        j.kv("scene", s.scene);
        j.kv("builder", s.builder);
        j.kv("reason", s.reason);
        j.end_object();
    }
    j.end_array();
    j.key("notices");
    j.begin_array();
    for (const auto& n : r.notices) j.value(n);
    j.end_array();
    j.key("sweep");
    if (r.sweep.empty()) {
        j.null();
    } else {
        j.begin_object();
        j.kv("reference", r.sweep_reference);
        j.key("scenes");
        j.begin_array();
        for (const auto& s : r.sweep_scenes) write_scene(j, s);
        j.end_array();
        j.key("settings");
        j.begin_array();
        for (const auto& x : r.sweep) {
            j.begin_object();
            j.kv("scene", x.scene);
            j.kv("group", x.group);
            j.kv("value", x.value);
            j.kv("setting", x.setting);
            j.kv("width", x.res.width);
            j.kv("height", x.res.height);
            j.kv("rays_per_frame", x.res.rays());
            write_summary(j, x.summary());
            j.kv("compared_pixels", x.compared_pixels);
            j.kv("hits_changed", x.changed);
            j.kv("hits_lost", x.lost);
            j.kv("hits_gained", x.gained);
            write_records(j, x.records);
            j.end_object();
        }
        j.end_array();
        j.end_object();
    }
    j.end_object();
    return j.str();
}

namespace {
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
                    "ms_shade\n";
    auto row = [&](const char* kind, const std::string& scene, const std::string& builder, const std::string& group, Resolution res,
                   const FrameRecord& f) {
        o += std::string(kind) + "," + csv_field(scene) + "," + csv_field(builder) + "," + csv_field(group) + "," +
             std::to_string(res.width) + "," + std::to_string(res.height) + "," + std::to_string(f.rep) + "," + std::to_string(f.frame) +
             "," + std::to_string(f.triangles) + "," + json_number(f.build_ms) + "," + json_number(f.trace_ms) + "," +
             (f.sah ? json_number(*f.sah) : "") + "," + (f.memory_bytes ? std::to_string(*f.memory_bytes) : "") + "," +
             std::to_string(f.hits);
        for (std::size_t k = 0; k < 4; ++k) o += "," + (f.effects ? std::to_string(f.effects->rays[k]) : std::string());
        for (std::size_t k = 0; k < 4; ++k) o += "," + (f.effects ? json_number(f.effects->ms[k]) : std::string());
        o += "," + (f.effects ? json_number(f.effects->shade_ms) : std::string()) + "\n";
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
