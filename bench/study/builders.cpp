#include "builders.hpp"

#include <charconv>
#include <cmath>
#include <sstream>
#include <stdexcept>


#include "auto_accel.hpp"
#include "embree_two_level.hpp"
#include "dyn_accel.hpp"
#include "options.hpp"

#if defined(DYNBVH_STUDY_EMBREE)
#include "../embree_bvh.hpp"
#endif

namespace dynbvh::study {

namespace {

struct KindName {
    Kind kind;
    const char* name;
};
constexpr KindName kind_names[] = {
    {Kind::lbvh, "lbvh"},           {Kind::kbvh, "kbvh"},
    {Kind::ploc, "ploc"},           {Kind::binned_sah, "binned-sah"},
    {Kind::refit, "refit"},         {Kind::embree_low, "embree-low"},
    {Kind::embree_medium, "embree-medium"}, {Kind::embree_refit, "embree-refit"},
    {Kind::dynamic, "auto"},        {Kind::two_level, "two-level"},
    {Kind::embree_two_level, "embree-two-level"}, {Kind::morton_wide, "morton-wide"},
};

std::string fmt_float(float v) {
    char buf[32];
    const auto r = std::to_chars(buf, buf + sizeof buf, v);
    return std::string(buf, r.ptr);
}

template <class T>
T knob_number(const std::string& spec, const std::string& key, const std::string& v) {
    T x{};
    const char* end = v.data() + v.size();
    const auto r = std::from_chars(v.data(), end, x);
    if (v.empty() || r.ec != std::errc() || r.ptr != end)
        throw std::invalid_argument("builder '" + spec + "': " + key + "=" + v + " is not a number");
    return x;
}

/// auto's own knobs: the rebuild builder ("auto:lbvh", second part only), rule=, th=, async=, and r=/bits= of that
/// builder. True when `part` was one of them; false leaves it to the knobs every builder of ours has.
bool parse_dynamic_knob(BuilderSpec& b, const std::string& spec, const std::string& part, std::size_t i) {
    const auto eq = part.find('=');
    if (eq == std::string::npos) {
        if (i != 1 || (part != "ploc" && part != "lbvh"))
            throw std::invalid_argument("builder '" + spec + "': auto's rebuild builder '" + part +
                                        "' must be ploc or lbvh, right after auto (auto:lbvh)");
        b.over = part == "lbvh" ? Kind::lbvh : Kind::ploc;
        return true;
    }
    const std::string key = part.substr(0, eq), v = part.substr(eq + 1);
    if (key == "th") {
        b.threshold = knob_number<double>(spec, key, v);
        if (!(b.threshold >= 0) || std::isinf(b.threshold))
            throw std::invalid_argument("builder '" + spec + "': th must be a finite number >= 0 (0 rebuilds every frame)");
        return true;
    }
    if (key == "rule") {
        if (v != "amortized" && v != "sah")
            throw std::invalid_argument("builder '" + spec + "': rule must be amortized (the default) or sah");
        b.amortized = v == "amortized";
        return true;
    }
    if (key == "async") {
        if (v != "0" && v != "1") throw std::invalid_argument("builder '" + spec + "': async must be 0 or 1");
        b.async = v == "1";
        return true;
    }
    if (key == "r") {
        if (b.over != Kind::ploc) throw std::invalid_argument("builder '" + spec + "': " + b.base() + ":lbvh has no knob 'r'");
        b.radius = knob_number<std::uint32_t>(spec, key, v);
        if (b.radius < 1 || b.radius > 65536) throw std::invalid_argument("builder '" + spec + "': r must be in 1..65536");
        return true;
    }
    if (key == "bits") {
        b.morton_bits = knob_number<int>(spec, key, v);
        if (b.morton_bits != 30 && b.morton_bits != 63) throw std::invalid_argument("builder '" + spec + "': bits must be 30 or 63");
        return true;
    }
    if (key == "prim" && v == "pre")
        throw std::invalid_argument("builder '" + spec + "': auto traces the indexed triangles only (prim=pre is not offered)");
    return false;
}

/// two-level's own knobs: its builder ("two-level:lbvh"), th= (each deforming object's rebuild threshold),
/// r=/bits=; it traces the binary trees (no wide=, box=, tri=, prim= knobs). False for leaf=.
bool parse_two_level_knob(BuilderSpec& b, const std::string& spec, const std::string& part, std::size_t i) {
    const auto eq = part.find('=');
    if (eq == std::string::npos) {
        if (i != 1 || (part != "ploc" && part != "lbvh"))
            throw std::invalid_argument("builder '" + spec + "': two-level's builder '" + part +
                                        "' must be ploc or lbvh, right after two-level (two-level:lbvh)");
        b.over = part == "lbvh" ? Kind::lbvh : Kind::ploc;
        return true;
    }
    const std::string key = part.substr(0, eq);
    if (key == "wide" || key == "box" || key == "tri" || key == "prim" || key == "async" || key == "rule")
        throw std::invalid_argument("builder '" + spec + "': two-level has no knob '" + key +
                                    "' (it traces binary trees with the robust tests, dynbvh::TwoLevel)");
    if (key == "th" || key == "r" || key == "bits") return parse_dynamic_knob(b, spec, part, i);
    return false;
}

} // namespace

std::string two_level_unsupported(const io::Frame& f) {
    if (f.objects.empty()) return "the scene's frames expose no objects";
    if (f.objects.size() < 2) return "the scene's frames expose one object only (nothing to instance)";
    std::size_t at = 0;
    for (const auto& o : f.objects) {
        if (o.first_triangle != at) return "the frame's objects do not tile its triangles in order";
        at += o.triangle_count;
    }
    if (at != f.triangles.size()) return "the frame's objects do not cover all its triangles";
    return {};
}

std::string BuilderSpec::base() const {
    for (const auto& k : kind_names)
        if (k.kind == kind) return k.name;
    return "?";
}

std::string BuilderSpec::name() const {
    const BuilderSpec d{.kind = kind, .blocks = default_blocks_for(kind, wide, precomputed)};
    std::string s = base();
    if ((kind == Kind::dynamic || kind == Kind::two_level || kind == Kind::refit) && over == Kind::lbvh) s += ":lbvh";
    if (radius != d.radius) s += ":r=" + std::to_string(radius);
    if (beta != d.beta) s += ":beta=" + fmt_float(beta);
    if (morton_bits != d.morton_bits) s += ":bits=" + std::to_string(morton_bits);
    if (max_leaf != d.max_leaf) s += ":leaf=" + std::to_string(max_leaf);
    if (bins != d.bins) s += ":bins=" + std::to_string(bins);
    if (fast_box) s += ":box=fast";
    if (fast_tri) s += ":tri=mt";
    if (precomputed) s += ":prim=pre";
    if (wide != d.wide) s += ":wide=" + std::to_string(wide);
    if (blocks != d.blocks) s += std::string(":blocks=") + (blocks ? "1" : "0");
    if (threshold != d.threshold) {
        char buf[32];
        const auto r = std::to_chars(buf, buf + sizeof buf, threshold);
        s += ":th=" + std::string(buf, r.ptr);
    }
    if (async) s += ":async=1";
    if (amortized != d.amortized) s += ":rule=sah";
    return s;
}

std::vector<std::string> all_builder_names() {
    std::vector<std::string> v;
    for (const auto& k : kind_names) v.push_back(k.name);
    return v;
}

BuilderSpec parse_builder(const std::string& spec) {
    const auto parts = split_list(spec, ':');
    if (parts.empty()) throw std::invalid_argument("empty builder name");
    BuilderSpec b;
    bool found = false;
    for (const auto& k : kind_names)
        if (parts[0] == k.name) {
            b.kind = k.kind;
            found = true;
        }
    if (!found) {
        std::string msg = "unknown builder '" + parts[0] + "'; valid:";
        for (const auto& k : kind_names) msg += std::string(" ") + k.name;
        throw std::invalid_argument(msg);
    }
    const bool ours = !b.is_embree();
    bool uses_radius = b.kind == Kind::ploc || b.kind == Kind::kbvh || b.kind == Kind::refit;
    const bool uses_bits = b.kind == Kind::ploc || b.kind == Kind::kbvh || b.kind == Kind::lbvh || b.kind == Kind::refit ||
                           b.kind == Kind::morton_wide;
    bool blocks_given = false;   // blocks= named: else the default for the kind, width and leaves (below)
    for (std::size_t i = 1; i < parts.size(); ++i) {
        if (b.kind == Kind::dynamic && parse_dynamic_knob(b, spec, parts[i], i)) continue;
        if (b.kind == Kind::two_level && parse_two_level_knob(b, spec, parts[i], i)) continue;
        if (b.kind == Kind::refit && i == 1 && (parts[i] == "ploc" || parts[i] == "lbvh")) {   // refit's builder: "refit:lbvh"
            b.over = parts[i] == "lbvh" ? Kind::lbvh : Kind::ploc;
            uses_radius = b.over == Kind::ploc;
            continue;
        }
        const auto eq = parts[i].find('=');
        if (eq == std::string::npos) throw std::invalid_argument("builder '" + spec + "': knob '" + parts[i] + "' is not key=value");
        const std::string key = parts[i].substr(0, eq), v = parts[i].substr(eq + 1);
        auto reject = [&] { throw std::invalid_argument("builder '" + spec + "': " + parts[0] + " has no knob '" + key + "'"); };
        if (key == "r") {
            if (!uses_radius) reject();
            b.radius = knob_number<std::uint32_t>(spec, key, v);
            if (b.radius < 1 || b.radius > 65536) throw std::invalid_argument("builder '" + spec + "': r must be in 1..65536");
        } else if (key == "beta") {
            if (b.kind != Kind::kbvh) reject();
            b.beta = knob_number<float>(spec, key, v);
            if (!(b.beta >= 0 && b.beta <= 4)) throw std::invalid_argument("builder '" + spec + "': beta must be in [0, 4]");
        } else if (key == "bits") {
            if (!uses_bits) reject();
            b.morton_bits = knob_number<int>(spec, key, v);
            if (b.morton_bits != 30 && b.morton_bits != 63) throw std::invalid_argument("builder '" + spec + "': bits must be 30 or 63");
        } else if (key == "leaf") {
            if (!ours) reject();
            b.max_leaf = knob_number<std::uint32_t>(spec, key, v);
            if (b.max_leaf < 1 || b.max_leaf > 256) throw std::invalid_argument("builder '" + spec + "': leaf must be in 1..256");
        } else if (key == "bins") {
            if (b.kind != Kind::binned_sah) reject();
            b.bins = knob_number<std::uint32_t>(spec, key, v);
            if (b.bins < 2 || b.bins > 1024) throw std::invalid_argument("builder '" + spec + "': bins must be in 2..1024");
        } else if (key == "box") {
            if (!ours) reject();
            if (v != "fast" && v != "robust") throw std::invalid_argument("builder '" + spec + "': box must be fast or robust");
            b.fast_box = v == "fast";
        } else if (key == "tri") {
            if (!ours) reject();
            if (v != "mt" && v != "watertight") throw std::invalid_argument("builder '" + spec + "': tri must be mt or watertight");
            b.fast_tri = v == "mt";
        } else if (key == "prim") {
            if (!ours) reject();
            if (v != "pre" && v != "indexed") throw std::invalid_argument("builder '" + spec + "': prim must be pre or indexed");
            b.precomputed = v == "pre";
        } else if (key == "wide") {
            if (!ours) reject();
            if (v != "0" && v != "4" && v != "8") throw std::invalid_argument("builder '" + spec + "': wide must be 0, 4 or 8");
            b.wide = v[0] - '0';
        } else if (key == "blocks") {
            if (!ours) reject();
            if (v != "0" && v != "1") throw std::invalid_argument("builder '" + spec + "': blocks must be 0 or 1");
            b.blocks = v == "1";
            blocks_given = true;
        } else {
            reject();
        }
    }
    if (b.kind == Kind::morton_wide && b.wide == 0)
        throw std::invalid_argument("builder '" + spec + "': morton-wide builds a wide tree only (wide=4 or 8)");
    if (b.kind == Kind::morton_wide && b.max_leaf > 255)
        throw std::invalid_argument("builder '" + spec + "': morton-wide's leaf must be in 1..255");
    if (!blocks_given) b.blocks = BuilderSpec::default_blocks_for(b.kind, b.wide, b.precomputed);
    if (b.blocks && b.wide == 0) throw std::invalid_argument("builder '" + spec + "': blocks=1 needs a wide tree (wide=4 or 8)");
    if (b.blocks && b.kind == Kind::two_level)
        throw std::invalid_argument("builder '" + spec + "': two-level's objects always trace blocks (no blocks knob)");
    return b;
}

bool embree_available() {
#if defined(DYNBVH_STUDY_EMBREE)
    return true;
#else
    return false;
#endif
}

std::string embree_version() {
#if defined(DYNBVH_STUDY_EMBREE) && defined(RTC_VERSION_STRING)
    return RTC_VERSION_STRING;
#elif defined(DYNBVH_STUDY_EMBREE)
    return "3";
#else
    return "";
#endif
}

namespace {

#if defined(DYNBVH_STUDY_EMBREE)
class EmbreeAccel final : public Accel {
public:
    EmbreeAccel(const BuilderSpec& spec, const Backend& backend)
        : bvh_(backend.threads(), spec.kind == Kind::embree_low      ? bench::EmbreeMode::low
                                  : spec.kind == Kind::embree_medium ? bench::EmbreeMode::medium
                                                                     : bench::EmbreeMode::refit),
          backend_(backend), packets_(spec.packets) {}
    void prepare(std::span<const Trianglef> tris) override { bvh_.update(tris); }
    void build(std::span<const Trianglef>) override { bvh_.commit(); }
    void trace(std::span<const Trianglef>, const RayGen& gen, std::span<std::uint32_t> out) override {
        const bench::EmbreeBvh& bvh = bvh_;
        if (packets_) {   // rtcIntersect16 on 4x4 pixels
            trace_tiles_packets<16>(backend_, gen, out, [&](const Rayf* rays, const int* valid, std::uint32_t* prims) {
                Hitf h[16];
                bvh.intersect_packet<16>(rays, valid, h);
                for (int k = 0; k < 16; ++k) prims[k] = h[k].prim;
            });
            return;
        }
        trace_tiles(backend_, gen, out, [&](const Rayf& r) { return bvh.intersect(r).prim; });
    }
    std::optional<double> sah() const override { return std::nullopt; }
    std::optional<std::size_t> memory_bytes() const override { return std::nullopt; }
    Hitf intersect(std::span<const Trianglef>, const Rayf& r) const override { return bvh_.intersect(r); }
    bool occluded(std::span<const Trianglef>, const Rayf& r) const override { return bvh_.occluded(r); }
    /// rtcIntersect16 / rtcOccluded16 when the study traces packets, else ray by ray.
    void intersect_packet(std::span<const Trianglef> tris, std::span<const Rayf> rays, std::span<Hitf> out) const override {
        if (!packets_) return Accel::intersect_packet(tris, rays, out);
        bench::EmbreeBvh::with_lanes16(rays, out, [&](const Rayf* r, const int* v, Hitf* h) { bvh_.intersect_packet<16>(r, v, h); });
    }
    void occluded_packet(std::span<const Trianglef> tris, std::span<const Rayf> rays, std::span<std::uint8_t> out) const override {
        if (!packets_) return Accel::occluded_packet(tris, rays, out);
        bench::EmbreeBvh::with_lanes16(rays, out, [&](const Rayf* r, const int* v, std::uint8_t* b) { bvh_.occluded_packet<16>(r, v, b); });
    }

private:
    bench::EmbreeBvh bvh_;
    const Backend& backend_;
    bool packets_;
};
#endif

} // namespace

std::unique_ptr<Accel> make_accel(const BuilderSpec& spec, const Backend& backend) {
    if (spec.kind == Kind::embree_two_level) return make_embree_two_level_accel(spec, backend);
    if (spec.is_embree()) {
#if defined(DYNBVH_STUDY_EMBREE)
        return std::make_unique<EmbreeAccel>(spec, backend);
#else
        throw std::runtime_error("builder " + spec.name() + ": this dynbvh-study was built without Embree 3 (install libembree-dev)");
#endif
    }
    if (spec.kind == Kind::two_level) return backend.visit([&](const auto& ex) { return make_two_level_accel(spec, ex, backend); });
    if (spec.kind == Kind::dynamic) return backend.visit([&](const auto& ex) { return make_auto_accel(spec, ex, backend); });
    return backend.visit([&](const auto& ex) { return make_dyn_accel(spec, ex, backend); });
}

void warm_up(const BuilderSpec& spec, const Backend& backend, std::span<const Trianglef> tris, const io::Camera& cam) {
    auto a = make_accel(spec, backend);
    std::vector<std::uint32_t> prims(64 * 48);
    a->prepare(tris);
    a->build(tris);
    a->release_previous();
    a->trace(tris, RayGen(cam, 64, 48), prims);
}

} // namespace dynbvh::study
