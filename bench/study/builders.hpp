// The builders the study compares, behind one interface: our four builders (plus refit) and
// Embree 3. A builder is named by a spec string, "ploc" or "ploc:r=16:leaf=4", so that the sweep
// and the command line share one vocabulary.
#pragma once

#include <cstdint>
#include <memory>
#include <optional>
#include <span>
#include <stdexcept>
#include <string>
#include <vector>

#include <dynbvh/ray.hpp>
#include <dynbvh/triangle.hpp>

#include "backend.hpp"
#include "camera.hpp"
#include "results.hpp"

namespace dynbvh::study {

enum class Kind { lbvh, kbvh, ploc, binned_sah, refit, embree_low, embree_medium, embree_refit,
                  morton_wide, ///< "morton-wide": dynbvh::morton_wide, the wide tree straight from the Morton codes
                  dynamic,  ///< "auto": dynbvh::Dynamic (refit or rebuild per frame) over `over`
                  two_level, ///< "two-level": dynbvh::TwoLevel over the frame's objects, `over` for every tree
                  embree_two_level ///< "embree-two-level": Embree 3 instancing over the frame's objects
};

/// A builder and its knobs (defaults = the library's defaults = the thesis's settings).
/// The wide tree the study traces by default: 8-wide when compiled with AVX (one AVX step tests a
/// node's eight boxes; e.g. tools/study.sh builds with -march=native), else 4-wide (one SSE step).
#if defined(__AVX__) && !defined(DYNBVH_NO_SIMD)
inline constexpr int default_wide = 8;
#else
inline constexpr int default_wide = 4;
#endif

/// Whether the study traces block-leaf trees (wide_blocks.hpp) by default: yes, for every builder of
/// ours that traces a wide tree over indexed triangles (lbvh, ploc, kbvh, binned-sah, refit, auto,
/// morton-wide; see default_blocks_for). Measured 2026-12-07 (dynbvh-study, built-in scenes at scale 1,
/// 4 frames, 2-3 reps, 2 threads, Xeon with AVX-512, against index leaves in the same run): 5-18 % more
/// FPS for lbvh, ploc and kbvh on n-body and cloth-ball at 854x480 and 1920x1080, and for ploc on all
/// five built-ins at 854x480. `blocks=0` gives the index-leaf wide tree.
inline constexpr bool default_blocks = true;

struct BuilderSpec {
    Kind kind = Kind::lbvh;
    std::uint32_t radius = 5;      ///< ploc, kbvh: PLOC search radius
    float beta = 0.05f;            ///< kbvh: presplit budget
    int morton_bits = 30;          ///< lbvh, ploc, kbvh, refit: 30 or 63
    std::uint32_t max_leaf = 8;    ///< every builder of ours: most references per leaf
    std::uint32_t bins = 32;       ///< binned-sah
    bool fast_box = false;         ///< box::fast instead of box::robust
    bool fast_tri = false;         ///< tri::moller_trumbore instead of tri::watertight
    bool precomputed = false;      ///< prim::copied instead of prim::indexed
    int wide = default_wide;       ///< trace a 4- or 8-wide tree converted from the binary one (wide.hpp; the
                                   ///< conversion is part of the timed build); wide=0: the binary traversal
    bool blocks = false;           ///< wide tree with leaves in SIMD triangle blocks of `wide` lanes, the binary
                                   ///< tree built with block_leaves (wide_blocks.hpp); needs wide=4 or 8
                                   ///< (parse_builder's default: default_blocks_for)
    Kind over = Kind::ploc;        ///< auto, two-level, refit: the builder its (re)builds use (ploc or lbvh: "auto:lbvh", "refit:lbvh")
    double threshold = 1.3;        ///< auto: rebuild past this many times the last rebuild's SAH ("th=1.5")
    bool async = false;            ///< auto: rebuild on a background thread, swap when ready ("async=1")
    bool amortized = true;         ///< auto: Dynamic's amortized rule, fed each frame's trace time ("rule=sah": the threshold)
    bool packets = true;           ///< primary rays in packets of 16 (the run's --rays; not part of the name)

    bool is_embree() const noexcept { return kind == Kind::embree_low || kind == Kind::embree_medium || kind == Kind::embree_refit || kind == Kind::embree_two_level; }
    /// Keeps a tree from frame to frame (refit, embree-refit).
    bool stateful() const noexcept { return kind == Kind::refit || kind == Kind::embree_refit || kind == Kind::dynamic || kind == Kind::two_level ||
                                      kind == Kind::embree_two_level; }
    /// A strategy holding a tree across frames that reports a decision per frame (auto).
    bool is_strategy() const noexcept { return kind == Kind::dynamic; }
    /// Canonical spec: the base name plus every knob that differs from the default ("ploc:r=16").
    std::string name() const;
    /// The base name ("ploc").
    std::string base() const;
    /// `blocks` by default for kind `k` with tree width `wide` and leaf triangles `precomputed`: the
    /// builders of ours whose traced tree is a wide tree over indexed triangles (see default_blocks);
    /// never for the binary tree (wide=0), for prim=pre (its own leaf layout), two-level (its objects
    /// always trace blocks) or Embree.
    static bool default_blocks_for(Kind k, int wide, bool precomputed) noexcept {
        const bool builds_wide = k == Kind::lbvh || k == Kind::ploc || k == Kind::kbvh || k == Kind::binned_sah ||
                                 k == Kind::refit || k == Kind::dynamic || k == Kind::morton_wide;
        return default_blocks && builds_wide && wide != 0 && !precomputed;
    }
};

/// Parses "ploc:r=16:leaf=4". Throws std::invalid_argument naming the spec and the problem.
BuilderSpec parse_builder(const std::string& spec);

/// Every builder name, ours first, Embree's last (whether or not Embree is compiled in).
std::vector<std::string> all_builder_names();

/// Whether this binary was built with Embree 3.
bool embree_available();
/// Embree's version string, or empty.
std::string embree_version();

/// One builder's acceleration structure for one run over a scene's frames.
class Accel {
public:
    virtual ~Accel() = default;
    /// Untimed, before prepare(): the frame's objects (runs of its triangles and their transforms); only
    /// two-level uses them. The span stays valid until the next call.
    virtual void frame_objects(std::span<const io::ObjectInstance> objects) { (void)objects; }
    /// Untimed: hand the frame's triangles over (Embree copies them into its buffers).
    virtual void prepare(std::span<const Trianglef> tris) { (void)tris; }
    /// Timed: build (or refit) the structure over `tris`.
    virtual void build(std::span<const Trianglef> tris) = 0;
    /// Untimed: free what the last build replaced.
    virtual void release_previous() {}
    /// Timed: one closest-hit ray per pixel of `gen`, in parallel over tiles; out[y * width + x] = the
    /// hit triangle's index or invalid_prim.
    virtual void trace(std::span<const Trianglef> tris, const RayGen& gen, std::span<std::uint32_t> out) = 0;
    /// SAH cost of the current tree (Ct = 3, Ci = 2); none for Embree.
    virtual std::optional<double> sah() const = 0;
    /// Bytes of the current tree; none for Embree.
    virtual std::optional<std::size_t> memory_bytes() const = 0;
    /// What the last build() decided (refit, rebuild, swap and the SAHs); none for per-frame builders.
    virtual std::optional<StrategyRecord> strategy() const { return std::nullopt; }
    /// Closest hit of one ray in the current structure (`tris` = the frame last built; the renderer's
    /// primary, reflection and refraction rays). Same tests as trace(). Throws std::logic_error when
    /// a structure does not implement single rays.
    virtual Hitf intersect(std::span<const Trianglef> tris, const Rayf& r) const {
        (void)tris;
        (void)r;
        throw std::logic_error("Accel::intersect: not implemented for this builder");
    }
    /// Whether anything is hit in [r.tmin, r.tmax] (the renderer's shadow rays); stops at the first hit.
    virtual bool occluded(std::span<const Trianglef> tris, const Rayf& r) const {
        (void)tris;
        (void)r;
        throw std::logic_error("Accel::occluded: not implemented for this builder");
    }
    /// Up to 16 rays at once (the renderer's primary and shadow rays): out[k] = intersect(tris, rays[k]),
    /// as packets where the structure traces them (spec.packets: our wide trees, Embree's rtcIntersect16).
    virtual void intersect_packet(std::span<const Trianglef> tris, std::span<const Rayf> rays, std::span<Hitf> out) const {
        for (std::size_t k = 0; k < rays.size(); ++k) out[k] = intersect(tris, rays[k]);
    }
    /// Up to 16 rays at once: out[k] = occluded(tris, rays[k]) (rtcOccluded16 for Embree).
    virtual void occluded_packet(std::span<const Trianglef> tris, std::span<const Rayf> rays, std::span<std::uint8_t> out) const {
        for (std::size_t k = 0; k < rays.size(); ++k) out[k] = occluded(tris, rays[k]) ? 1 : 0;
    }
};

/// An Accel and its frame's triangles as a render::Tracer (bench/render/whitted.hpp).
struct AccelTracer {
    const Accel& accel;
    std::span<const Trianglef> tris;
    Hitf intersect(const Rayf& r) const { return accel.intersect(tris, r); }
    bool occluded(const Rayf& r) const { return accel.occluded(tris, r); }
    void intersect_packet(std::span<const Rayf> r, std::span<Hitf> out) const { accel.intersect_packet(tris, r, out); }
    void occluded_packet(std::span<const Rayf> r, std::span<std::uint8_t> out) const { accel.occluded_packet(tris, r, out); }
};

/// Why `frame`'s objects cannot serve a two-level run (empty when they can): two-level needs at least two
/// objects tiling the frame's triangles in order.
std::string two_level_unsupported(const io::Frame& frame);

/// Makes the structure for `spec`, running on `backend` (kept by reference: it must outlive the Accel).
/// Throws std::runtime_error for an Embree builder in a binary without Embree.
std::unique_ptr<Accel> make_accel(const BuilderSpec& spec, const Backend& backend);

/// Untimed warm-up before the timed frames: makes `spec`'s structure, builds it over `tris` and traces
/// a 64x48 image from `cam` once (code, thread pools and allocator caches are then warm).
void warm_up(const BuilderSpec& spec, const Backend& backend, std::span<const Trianglef> tris, const io::Camera& cam);

} // namespace dynbvh::study
