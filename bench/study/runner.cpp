#include "runner.hpp"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <optional>
#include <stdexcept>

#include <dynbvh/io/frames.hpp>
#include <dynbvh/ray.hpp>
#include <scenes/builtin.hpp>

#include "image.hpp"
#include "machine.hpp"
#include "sweep.hpp"

namespace dynbvh::study {

std::vector<std::uint32_t> select_frames(std::size_t total, std::size_t limit, std::size_t step) {
    std::vector<std::uint32_t> ids;
    if (total == 0) return ids;
    if (step == 0) {
        if (limit == 0 || limit >= total) {
            for (std::size_t i = 0; i < total; ++i) ids.push_back(std::uint32_t(i));
        } else if (limit == 1) {
            ids.push_back(0);
        } else {
            for (std::size_t i = 0; i < limit; ++i) {
                const auto f = std::uint32_t(std::llround(double(i) * double(total - 1) / double(limit - 1)));
                if (ids.empty() || ids.back() != f) ids.push_back(f);
            }
        }
        return ids;
    }
    for (std::size_t i = 0; i < total; i += step) {
        if (limit && ids.size() >= limit) break;
        ids.push_back(std::uint32_t(i));
    }
    return ids;
}

FrameSource::FrameSource(io::Scene& scene, std::vector<std::uint32_t> ids, std::size_t budget_bytes)
    : scene_(scene), ids_(std::move(ids)) {
    if (ids_.empty()) return;
    scene_.frame(ids_[0], scratch_);
    scratch_k_ = 0;
    first_triangles_ = scratch_.triangles.size();
    const double per_frame = double(first_triangles_) * double(sizeof(Trianglef) + sizeof(std::uint32_t)) * 1.2;
    if (per_frame * double(ids_.size()) <= double(budget_bytes)) {
        cache_.resize(ids_.size());
        cache_[0] = scratch_;
        for (std::size_t k = 1; k < ids_.size(); ++k) scene_.frame(ids_[k], cache_[k]);
        scratch_ = io::Frame{};
    }
}

const io::Frame& FrameSource::get(std::size_t k) {
    if (!cache_.empty()) return cache_[k];
    if (scratch_k_ != k) {
        scene_.frame(ids_[k], scratch_);
        scratch_k_ = k;
    }
    return scratch_;
}

void run_frames(FrameSource& src, const BuilderSpec& spec, const Backend& backend, Resolution res, std::uint32_t rep,
                std::vector<FrameRecord>& out, Progress* progress, const std::string& label, const FrameHook& hook,
                EffectsSetup* effects) {
    using clock = std::chrono::steady_clock;
    auto accel = make_accel(spec, backend);
    std::vector<std::uint32_t> prims(res.rays());
    for (std::size_t k = 0; k < src.size(); ++k) {
        const io::Frame& f = src.get(k);
        const std::span<const Trianglef> tris(f.triangles);
        accel->frame_objects(f.objects);
        accel->prepare(tris);
        const auto t0 = clock::now();
        accel->build(tris);
        const auto t1 = clock::now();
        accel->release_previous();
        const RayGen gen(f.camera, res.width, res.height);
        const auto t2 = clock::now();
        accel->trace(tris, gen, prims);
        const auto t3 = clock::now();
        FrameRecord r;
        r.rep = rep;
        r.frame = src.id(k);
        r.triangles = tris.size();
        r.build_ms = std::chrono::duration<double, std::milli>(t1 - t0).count();
        r.trace_ms = std::chrono::duration<double, std::milli>(t3 - t2).count();
        r.sah = accel->sah();
        r.memory_bytes = accel->memory_bytes();
        r.strategy = accel->strategy();
        r.hits = std::size_t(std::count_if(prims.begin(), prims.end(), [](std::uint32_t p) { return p != invalid_prim; }));
        if (effects) {
            const render::Stats st = render::render(AccelTracer{*accel, tris}, render::scene_view(f, src.scene()), gen, effects->image,
                                                    effects->config, backend);
            EffectsRecord e;
            e.rays = st.rays;
            e.ms = st.trace_ms;
            e.shade_ms = st.shade_ms;
            e.depth = st.depth_reached;
            r.effects = e;
        }
        out.push_back(r);
        if (hook) hook(k, f, prims);
        if (progress) progress->advance(frame_weight(res.rays(), tris.size()), label);
    }
}

namespace {

struct PlannedScene {
    OpenedScene opened;
    SceneSummary summary;
};

SceneSummary summary_of(const OpenedScene& s, const std::vector<std::uint32_t>& ids) {
    SceneSummary m;
    const auto& info = s.scene->info();
    m.name = s.name;
    m.spec = s.spec;
    m.kind = s.kind;
    m.format = s.format;
    m.motion = io::to_string(info.motion);
    m.topology_changes = info.topology_changes;
    m.scale = s.scale;
    m.frames_total = s.scene->frame_count();
    m.frames_used = ids;
    m.materials = info.materials.size();
    m.lights = info.lights.size();
    return m;
}

std::vector<BuilderSpec> plan_builders(const Options& opt, StudyResults& res, Progress* note_to) {
    std::vector<std::string> names = opt.builders.empty() ? all_builder_names() : opt.builders;
    std::vector<BuilderSpec> specs;
    for (const auto& n : names) {
        BuilderSpec b = parse_builder(n);
        b.packets = opt.packets;
        if (b.is_embree() && !embree_available()) {
            res.skipped.push_back({"*", b.name(), "built without Embree 3 (install libembree-dev and rebuild)"});
            continue;
        }
        if (std::none_of(specs.begin(), specs.end(), [&](const BuilderSpec& s) { return s.name() == b.name(); }))
            specs.push_back(b);
    }
    if (!embree_available() && std::any_of(names.begin(), names.end(), [](const std::string& n) { return n.rfind("embree", 0) == 0; })) {
        const std::string msg = "dynbvh-study: notice: Embree builders skipped: this binary was built without Embree 3 "
                                "(install libembree-dev, e.g. with tools/deps.sh, and rebuild)";
        res.notices.push_back(msg);
        if (note_to) note_to->note(msg);
        else std::fprintf(stderr, "%s\n", msg.c_str());
    }
    return specs;
}

} // namespace

StudyResults run_study(const Options& opt, const Backend& backend) {
    const auto wall0 = std::chrono::steady_clock::now();
    StudyResults res;
    res.machine = machine_info();
    res.backend = backend.name();
    res.threads = backend.threads();
    res.options = opt;
    const std::vector<BuilderSpec> specs = plan_builders(opt, res, nullptr);
    for (const auto& s : specs) res.builders.push_back(s.name());
    std::filesystem::create_directories(opt.out);
    std::filesystem::create_directories(std::filesystem::path(opt.out) / "images");

    const SceneOptions so{.scale = opt.scale, .seed = opt.seed};
    std::vector<std::string> scene_specs = opt.scenes;
    if (scene_specs.empty())
        for (std::string_view n : scenes::builtin_names()) scene_specs.emplace_back(n);

    if (!opt.sweep_only) {
        // Open every scene first: bad names fail before anything is measured, and the progress bar
        // knows the work ahead.
        std::vector<PlannedScene> planned;
        double total = 0;
        for (const auto& spec : scene_specs) {
            PlannedScene p{open_scene(spec, so), {}};
            const auto ids = select_frames(p.opened.scene->frame_count(), opt.frames, opt.frame_step);
            p.summary = summary_of(p.opened, ids);
            std::size_t est = 0;
            {
                io::Frame f;
                p.opened.scene->frame(ids.empty() ? 0 : ids[0], f);
                est = f.triangles.size();
            }
            for (const auto& r : opt.resolutions) total += double(specs.size()) * double(opt.reps) * double(ids.size()) * frame_weight(r.rays(), est);
            planned.push_back(std::move(p));
        }
        Progress progress(total);
        for (auto& p : planned) {
            SceneSummary& sum = p.summary;
            io::Scene& scene = *p.opened.scene;
            FrameSource src(scene, sum.frames_used, opt.cache_mb << 20);
            if (!src.cached() && src.size() > 1)
                progress.note("dynbvh-study: " + sum.name + ": frames do not fit in --cache-mb " + std::to_string(opt.cache_mb) +
                              "; they are generated again (untimed) for every run");
            sum.triangles_min = ~std::size_t(0);
            for (std::size_t k = 0; k < src.size(); ++k) {
                if (!src.cached() && k > 0) break;   // counts from the first frame only when not cached
                sum.triangles_min = std::min(sum.triangles_min, src.get(k).triangles.size());
                sum.triangles_max = std::max(sum.triangles_max, src.get(k).triangles.size());
            }
            if (src.size() == 0) sum.triangles_min = 0;

            std::vector<BuilderSpec> run_specs;
            for (const auto& b : specs) {
                if (b.kind == Kind::refit && sum.topology_changes) {
                    res.skipped.push_back({sum.name, b.name(), "topology changes between frames; refit keeps the tree's triangle set"});
                    progress.note("dynbvh-study: notice: " + sum.name + ": refit skipped (topology changes between frames)");
                    // keep the progress total honest
                    for (const auto& r : opt.resolutions)
                        progress.advance(double(opt.reps) * double(src.size()) * frame_weight(r.rays(), src.first_triangles()), sum.name);
                    continue;
                }
                if ((b.kind == Kind::two_level || b.kind == Kind::embree_two_level) && src.size() > 0) {
                    if (const std::string why = two_level_unsupported(src.get(0)); !why.empty()) {
                        res.skipped.push_back({sum.name, b.name(), why});
                        progress.note("dynbvh-study: notice: " + sum.name + ": " + b.name() + " skipped (" + why + ")");
                        for (const auto& r : opt.resolutions)
                            progress.advance(double(opt.reps) * double(src.size()) * frame_weight(r.rays(), src.first_triangles()), sum.name);
                        continue;
                    }
                }
                run_specs.push_back(b);
            }
            if (opt.warmup && src.size() > 0) {
                const io::Frame& f = src.get(0);
                for (const auto& b : run_specs) warm_up(b, backend, f.triangles, f.camera);
            }
            // Which frames to render: evenly spread over those used.
            std::vector<std::size_t> image_ks;
            if (opt.images > 0 && src.size() > 0) {
                for (auto id : select_frames(src.size(), opt.images, 0)) image_ks.push_back(id);
            }
            // Groups of this scene, in builder x resolution order.
            const std::size_t first_group = res.groups.size();
            for (const auto& r : opt.resolutions)
                for (const auto& b : run_specs) res.groups.push_back({sum.name, b.name(), r, {}});
            std::optional<EffectsSetup> fx;
            if (opt.effects) {
                fx.emplace();
                fx->config.max_depth = opt.effects_depth;
            }
            for (int rep = 0; rep < opt.reps; ++rep) {
                for (std::size_t ri = 0; ri < opt.resolutions.size(); ++ri) {
                    const Resolution r = opt.resolutions[ri];
                    for (std::size_t bi = 0; bi < run_specs.size(); ++bi) {
                        GroupResult& g = res.groups[first_group + ri * run_specs.size() + bi];
                        FrameHook hook;
                        if (rep == 0 && ri == 0 && bi == 0 && !image_ks.empty()) {
                            hook = [&](std::size_t k, const io::Frame& f, std::span<const std::uint32_t> prims) {
                                if (std::find(image_ks.begin(), image_ks.end(), k) == image_ks.end()) return;
                                ImageRecord im;
                                im.scene = sum.name;
                                im.frame = src.id(k);
                                im.builder = g.builder;
                                im.res = r;
                                char name[256];
                                std::snprintf(name, sizeof name, "images/%s_%04u.png", safe_file_name(sum.name).c_str(), unsigned(im.frame));
                                im.file = name;
                                const std::string path = (std::filesystem::path(opt.out) / im.file).string();
                                if (fx) {
                                    write_linear_png(path, fx->image.width, fx->image.height, fx->image.pixels);
                                    im.hit_pixels = std::size_t(std::count_if(prims.begin(), prims.end(),
                                                                               [](std::uint32_t p) { return p != invalid_prim; }));
                                } else {
                                    im.hit_pixels = render_png(path, f, scene.info(), RayGen(f.camera, r.width, r.height), prims);
                                }
                                res.images.push_back(im);
                            };
                        }
                        const std::string label = sum.name + " " + g.builder + " " + r.str() +
                                                  (opt.reps > 1 ? " rep " + std::to_string(rep + 1) : "");
                        run_frames(src, run_specs[bi], backend, r, std::uint32_t(rep), g.records, &progress, label, hook,
                                   fx ? &*fx : nullptr);
                    }
                }
            }
            res.scenes.push_back(sum);
            p.opened.scene.reset();   // free the scene before the next one
        }
        progress.finish("study measured");
    }
    if (opt.sweep) {
        const std::vector<std::string> sweep_specs = opt.sweep_scenes.empty() ? scene_specs : opt.sweep_scenes;
        run_sweep(opt, backend, sweep_specs, res);
    }
    res.wall_s = std::chrono::duration<double>(std::chrono::steady_clock::now() - wall0).count();
    return res;
}

} // namespace dynbvh::study
