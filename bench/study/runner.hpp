// The measurement loop: for each scene x repetition x resolution x builder, every selected frame is
// produced (untimed), built (timed) and traced one ray per pixel (timed); SAH, memory and hits are
// taken afterwards (untimed).
#pragma once

#include <functional>
#include <span>
#include <string>
#include <vector>

#include <dynbvh/io/scene.hpp>

#include <render/whitted.hpp>
#include "backend.hpp"
#include "builders.hpp"
#include "options.hpp"
#include "progress.hpp"
#include "results.hpp"
#include "scene_open.hpp"

namespace dynbvh::study {

/// Everything one invocation measured.
struct StudyResults {
    MachineInfo machine;
    std::string backend;
    int threads = 1;
    Options options;
    std::vector<std::string> builders;     ///< canonical names, in the order run
    std::vector<SceneSummary> scenes;
    std::vector<GroupResult> groups;
    std::vector<ImageRecord> images;
    std::vector<Skip> skipped;
    std::vector<std::string> notices;
    std::vector<SceneSummary> sweep_scenes;
    std::vector<SweepResult> sweep;
    std::string sweep_reference;           ///< the setting hits are compared with
    double wall_s = 0;
};

/// Frame indices to use out of `total`: at most `limit` (0: all), every `step`-th (0: spread evenly).
std::vector<std::uint32_t> select_frames(std::size_t total, std::size_t limit, std::size_t step);

/// Produces a scene's selected frames before they are timed: all kept in memory when they fit in
/// the budget, otherwise evaluated again on each request (never inside a timed region).
class FrameSource {
public:
    FrameSource(io::Scene& scene, std::vector<std::uint32_t> ids, std::size_t budget_bytes);
    std::size_t size() const noexcept { return ids_.size(); }
    std::uint32_t id(std::size_t k) const noexcept { return ids_[k]; }
    const io::Frame& get(std::size_t k);
    bool cached() const noexcept { return !cache_.empty(); }
    /// The scene (materials, lights and, for BART, the background: for --effects auto).
    const io::Scene& scene() const noexcept { return scene_; }
    std::size_t first_triangles() const noexcept { return first_triangles_; }

private:
    io::Scene& scene_;
    std::vector<std::uint32_t> ids_;
    std::vector<io::Frame> cache_;
    io::Frame scratch_;
    std::size_t scratch_k_ = ~std::size_t(0);
    std::size_t first_triangles_ = 0;
};

/// Called after every traced frame with the frame's position k, the frame and the hit triangles.
using FrameHook = std::function<void(std::size_t k, const io::Frame& f, std::span<const std::uint32_t> prims)>;

/// --effects auto: after each frame's primary trace, the frame is rendered Whitted-style
/// (bench/render/whitted.hpp) through the same structure's queries (primary rays in packets of 16 with
/// --rays packet, shadow, reflection and refraction rays one at a time); the counts and
/// times per kind go into FrameRecord::effects (build_ms and trace_ms are not affected).
struct EffectsSetup {
    render::Config config;
    render::Image image;   ///< the last frame's render (linear RGB): what the hook writes as PNG
};

/// Runs `spec` over every frame of `src` at `res` and appends one record per frame; with `effects`
/// each frame is also rendered with secondary effects (see EffectsSetup) before `hook` is called.
void run_frames(FrameSource& src, const BuilderSpec& spec, const Backend& backend, Resolution res, std::uint32_t rep,
                std::vector<FrameRecord>& out, Progress* progress, const std::string& label, const FrameHook& hook = {},
                EffectsSetup* effects = nullptr);

/// Work units of one frame for the progress bar (tracing dominates; building weighs in by triangles).
inline double frame_weight(std::size_t rays, std::size_t triangles) { return double(rays) + 8.0 * double(triangles); }

/// The whole study (and the sweep when asked). Notices go to stderr as they happen.
StudyResults run_study(const Options& opt, const Backend& backend);

} // namespace dynbvh::study
