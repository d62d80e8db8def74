#include "sweep.hpp"

#include <algorithm>
#include <map>

namespace dynbvh::study {

BuilderSpec sweep_reference() { return parse_builder("ploc"); }

std::vector<SweepSetting> sweep_settings(bool small, bool embree) {
    std::vector<SweepSetting> v;
    auto add = [&](const std::string& group, const std::string& value, const std::string& spec, bool ordered = true) {
        v.push_back({group, value, parse_builder(spec), ordered});
    };
    const std::vector<int> radii = small ? std::vector<int>{1, 5, 16, 64} : std::vector<int>{1, 2, 3, 5, 8, 10, 16, 25, 32, 64};
    for (int r : radii) add("ploc radius", "r=" + std::to_string(r), "ploc:r=" + std::to_string(r));
    const std::vector<std::string> betas =
        small ? std::vector<std::string>{"0", "0.05", "0.2", "0.5"} : std::vector<std::string>{"0", "0.025", "0.05", "0.1", "0.2", "0.3", "0.5"};
    for (const auto& b : betas) add("presplit budget (kbvh)", "beta=" + b, "kbvh:beta=" + b);
    add("Morton bits", "lbvh 30", "lbvh", false);
    add("Morton bits", "lbvh 63", "lbvh:bits=63", false);
    if (!small) {
        add("Morton bits", "ploc 30", "ploc", false);
        add("Morton bits", "ploc 63", "ploc:bits=63", false);
    }
    const std::vector<int> leaves = small ? std::vector<int>{1, 4, 8, 16} : std::vector<int>{1, 2, 4, 8, 16, 32};
    for (int l : leaves) add("max leaf size (ploc)", "leaf=" + std::to_string(l), "ploc:leaf=" + std::to_string(l));
    add("triangle test", "watertight", "ploc", false);
    add("triangle test", "Moller-Trumbore", "ploc:tri=mt", false);
    add("box test", "robust", "ploc", false);
    add("box test", "fast", "ploc:box=fast", false);
    add("box test", "fast + Moller-Trumbore", "ploc:box=fast:tri=mt", false);
    add("leaf triangles", "SIMD blocks", "ploc", false);
    add("leaf triangles", "indexed", "ploc:blocks=0", false);
    add("leaf triangles", "precomputed", "ploc:prim=pre", false);
    const int other_wide = default_wide == 8 ? 4 : 8;
    add("tree layout", std::to_string(default_wide) + "-wide", "ploc", false);
    add("tree layout", std::to_string(other_wide) + "-wide", "ploc:wide=" + std::to_string(other_wide), false);
    add("tree layout", "binary", "ploc:wide=0", false);
    for (const char* b : {"ploc", "lbvh", "kbvh", "binned-sah", "refit"}) add("builder", b, b, false);
    if (embree)
        for (const char* b : {"embree-low", "embree-medium", "embree-refit"}) add("builder", b, b, false);
    return v;
}

void run_sweep(const Options& opt, const Backend& backend, const std::vector<std::string>& scene_specs, StudyResults& res) {
    const Resolution r = opt.resolutions.front();
    const auto settings = sweep_settings(opt.sweep_small, embree_available());
    const BuilderSpec ref = sweep_reference();
    const int reps = opt.sweep_reps > 0 ? opt.sweep_reps : opt.reps;
    res.sweep_reference = ref.name() + " (robust box test, watertight triangles)";
    // Distinct specs, reference first.
    std::vector<BuilderSpec> distinct{ref};
    for (const auto& s : settings)
        if (std::none_of(distinct.begin(), distinct.end(), [&](const BuilderSpec& d) { return d.name() == s.spec.name(); }))
            distinct.push_back(s.spec);
    for (auto& d : distinct) d.packets = opt.packets;   // the run's --rays

    const SceneOptions so{.scale = opt.scale, .seed = opt.seed};
    struct Planned {
        OpenedScene opened;
        std::vector<std::uint32_t> ids;
        std::size_t tris = 0;
    };
    std::vector<Planned> planned;
    double total = 0;
    for (const auto& spec : scene_specs) {
        Planned p{open_scene(spec, so), {}, 0};
        p.ids = select_frames(p.opened.scene->frame_count(), opt.frames, opt.frame_step);
        io::Frame f;
        p.opened.scene->frame(p.ids.empty() ? 0 : p.ids[0], f);
        p.tris = f.triangles.size();
        total += double(reps) * double(distinct.size()) * double(p.ids.size()) * frame_weight(r.rays(), p.tris);
        planned.push_back(std::move(p));
    }
    Progress progress(total);
    for (auto& p : planned) {
        io::Scene& scene = *p.opened.scene;
        const bool topo = scene.info().topology_changes;
        SceneSummary sum;
        sum.name = p.opened.name;
        sum.spec = p.opened.spec;
        sum.kind = p.opened.kind;
        sum.format = p.opened.format;
        sum.motion = io::to_string(scene.info().motion);
        sum.topology_changes = topo;
        sum.scale = p.opened.scale;
        sum.frames_total = scene.frame_count();
        sum.frames_used = p.ids;
        sum.triangles_min = sum.triangles_max = p.tris;
        FrameSource src(scene, p.ids, opt.cache_mb << 20);
        if (opt.warmup && src.size() > 0) {
            const io::Frame& f = src.get(0);
            for (const auto& b : distinct)
                if (!(b.kind == Kind::refit && topo)) warm_up(b, backend, f.triangles, f.camera);
        }
        // Reference hits per frame.
        std::vector<std::vector<std::uint32_t>> ref_prims(src.size());
        struct Run {
            std::vector<FrameRecord> records;
            std::size_t compared = 0, changed = 0, lost = 0, gained = 0;
        };
        std::map<std::string, Run> runs;
        for (int rep = 0; rep < reps; ++rep) {
            for (const auto& b : distinct) {
                const std::string name = b.name();
                if (b.kind == Kind::refit && topo) {
                    if (rep == 0) res.skipped.push_back({sum.name, "sweep " + name, "topology changes between frames"});
                    progress.advance(double(src.size()) * frame_weight(r.rays(), p.tris), name);
                    continue;
                }
                Run& run = runs[name];
                const bool is_ref = name == ref.name();
                FrameHook hook;
                if (rep == 0)   // hits are the same in every repetition: compare once
                    hook = [&](std::size_t k, const io::Frame&, std::span<const std::uint32_t> prims) {
                        if (is_ref) {
                            ref_prims[k].assign(prims.begin(), prims.end());
                            run.compared += prims.size();
                            return;
                        }
                        const auto& rp = ref_prims[k];
                        run.compared += prims.size();
                        for (std::size_t i = 0; i < prims.size(); ++i) {
                            const bool a = rp[i] != invalid_prim, c = prims[i] != invalid_prim;
                            if (a && c && rp[i] != prims[i]) ++run.changed;
                            else if (a && !c) ++run.lost;
                            else if (!a && c) ++run.gained;
                        }
                    };
                run_frames(src, b, backend, r, std::uint32_t(rep), run.records, &progress,
                           "sweep " + sum.name + " " + name + (reps > 1 ? " rep " + std::to_string(rep + 1) : ""), hook);
            }
        }
        for (const auto& s : settings) {
            const auto it = runs.find(s.spec.name());
            if (it == runs.end()) continue;
            SweepResult x;
            x.scene = sum.name;
            x.group = s.group;
            x.setting = s.spec.name();
            x.value = s.value;
            x.ordered = s.ordered;
            x.res = r;
            x.records = it->second.records;
            x.compared_pixels = it->second.compared;
            x.changed = it->second.changed;
            x.lost = it->second.lost;
            x.gained = it->second.gained;
            res.sweep.push_back(std::move(x));
        }
        res.sweep_scenes.push_back(sum);
        p.opened.scene.reset();
    }
    progress.finish("sweep measured");
}

} // namespace dynbvh::study
