#include "scene_open.hpp"

#include <algorithm>
#include <cmath>
#include <filesystem>
#include <stdexcept>

#include <dynbvh/io/bart.hpp>
#include <dynbvh/io/frames.hpp>
#include <render/material.hpp>
#include <scenes/builtin.hpp>

#include <nlohmann/json.hpp>

#include "output.hpp"

namespace dynbvh::study {

namespace {

std::string lower_ext(const std::string& path) {
    std::string e = std::filesystem::path(path).extension().string();
    for (auto& c : e) c = char(c >= 'A' && c <= 'Z' ? c - 'A' + 'a' : c);
    return e;
}

std::string format_of_files(const std::vector<std::string>& files) {
    std::string f;
    for (const auto& p : files) {
        const std::string e = lower_ext(p).substr(1);
        if (f.empty()) f = e;
        else if (f != e) return "mixed";
    }
    return f;
}

} // namespace

OpenedScene open_scene(const std::string& spec, const SceneOptions& opt) {
    OpenedScene s;
    s.spec = spec;
    for (std::string_view n : scenes::builtin_names()) {
        if (spec == n) {
            s.scene = scenes::make_builtin(n, {.seed = opt.seed, .scale = opt.scale});
            s.name = spec;
            s.kind = "builtin";
            s.format = "builtin";
            s.scale = opt.scale;
            return s;
        }
    }
    namespace fs = std::filesystem;
    std::error_code ec;
    const std::string ext = lower_ext(spec);
    if (ext == ".aff") {
        s.scene = io::load_bart(spec);
        s.kind = "bart";
        s.format = "aff";
    } else if (spec.find('%') != std::string::npos || fs::is_directory(spec, ec)) {
        s.format = format_of_files(io::list_frames(spec));
        s.scene = io::open_frames(spec);
        s.kind = "frames";
    } else if (fs::is_regular_file(spec, ec) && (ext == ".ply" || ext == ".obj")) {
        s.scene = io::open_mesh_scene(spec);
        s.kind = "mesh";
        s.format = ext.substr(1);
    } else if (fs::exists(spec, ec)) {
        throw std::invalid_argument("scene '" + spec + "': unknown format (expected .ply, .obj, .aff, a frame pattern or a directory)");
    } else {
        std::string msg = "scene '" + spec + "': no such file, directory or pattern, and not a built-in scene (";
        bool first = true;
        for (std::string_view n : scenes::builtin_names()) {
            msg += (first ? "" : ", ") + std::string(n);
            first = false;
        }
        throw std::invalid_argument(msg + ")");
    }
    s.name = s.scene->info().name.empty() ? fs::path(spec).stem().string() : s.scene->info().name;
    return s;
}

std::string scene_info_json(OpenedScene& s, std::size_t max_frames) {
    const io::SceneInfo& info = s.scene->info();
    const std::size_t total = s.scene->frame_count();
    const std::size_t n = max_frames == 0 ? total : std::min(total, max_frames);
    io::Frame f, prev;
    AABBf bounds;
    std::size_t tmin = ~std::size_t(0), tmax = 0, first_tris = 0, objects = 0;
    double motion_sum = 0;
    std::size_t motion_steps = 0, non_finite = 0;
    bool count_changed = false;
    for (std::size_t i = 0; i < n; ++i) {
        s.scene->frame(i, f);
        if (i == 0) {
            first_tris = f.triangles.size();
            objects = f.objects.size();
        }
        tmin = std::min(tmin, f.triangles.size());
        tmax = std::max(tmax, f.triangles.size());
        AABBf fb;
        for (const auto& t : f.triangles) {
            if (!t.is_finite()) { ++non_finite; continue; }
            fb.extend(t.bounds());
        }
        bounds.extend(fb);
        if (i > 0) {
            if (prev.triangles.size() == f.triangles.size()) {
                // Mean displacement of the triangles' vertices, relative to this frame's diagonal.
                double d = 0;
                for (std::size_t k = 0; k < f.triangles.size(); ++k) {
                    const auto& a = prev.triangles[k];
                    const auto& b = f.triangles[k];
                    d += double(length(b.p0 - a.p0)) + double(length(b.p1 - a.p1)) + double(length(b.p2 - a.p2));
                }
                const double diag = double(length(fb.diagonal()));
                if (!f.triangles.empty() && diag > 0) {
                    motion_sum += d / (3.0 * double(f.triangles.size())) / diag;
                    ++motion_steps;
                }
            } else {
                count_changed = true;
            }
        }
        std::swap(prev, f);
    }
    using Json = nlohmann::ordered_json;
    auto vec3 = [](const auto& v) { return Json::array({v.x, v.y, v.z}); };
    Json j;
    j["spec"] = s.spec;
    j["name"] = s.name;
    j["kind"] = s.kind;
    j["format"] = s.format;
    if (s.kind == "builtin") j["scale"] = s.scale;
    j["triangles"] = first_tris;
    j["triangles_min"] = n ? tmin : 0;
    j["triangles_max"] = tmax;
    j["non_finite_triangles"] = non_finite;
    j["frames"] = total;
    j["frames_inspected"] = n;
    j["bounds"] = {{"min", vec3(bounds.min)}, {"max", vec3(bounds.max)}};
    j["motion"] = std::string(io::to_string(info.motion));
    j["topology_changes"] = info.topology_changes || count_changed;
    j["mean_vertex_motion_per_frame"] = motion_steps ? Json(motion_sum / double(motion_steps)) : Json(nullptr);
    j["objects"] = objects;
    j["materials"] = info.materials.size();
    j["lights"] = info.lights.size();
    std::size_t reflective = 0, refractive = 0;
    for (const auto& m : info.materials) {
        reflective += render::reflects(m);
        refractive += render::refracts(m);
    }
    j["reflective_materials"] = reflective;
    j["refractive_materials"] = refractive;
    if (n) {
        s.scene->frame(0, f);
        j["camera"] = {{"from", vec3(f.camera.from)}, {"at", vec3(f.camera.at)}, {"up", vec3(f.camera.up)},
                       {"fov_y_deg", f.camera.fov_y_deg}};
    }
    return json_text(j);
}

} // namespace dynbvh::study
