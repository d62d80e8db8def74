// dynbvh-render: one frame of a scene rendered Whitted-style (shadows, reflection, refraction where
// the scene's lights and materials call for them) to PNG, with the rays traced per kind.
//
//   dynbvh-render --scene funnel --frame 110 --out funnel.png
//   dynbvh-render --scene ../shared/data/bart/kitchen/kitchen.aff --builder embree-low --out kitchen.png
//
// Scenes are what dynbvh-study accepts (built-in names, PLY/OBJ files or frame sequences, BART .aff);
// builders too (lbvh, ploc, kbvh, binned-sah, embree-low, ...). The renderer is bench/render/whitted.hpp.
#include <cstdio>
#include <exception>
#include <stdexcept>
#include <string>

#include <render/whitted.hpp>

#include "backend.hpp"
#include "builders.hpp"
#include "camera.hpp"
#include "image.hpp"
#include "options.hpp"
#include "scene_open.hpp"

using namespace dynbvh;

namespace {

const char* usage_text =
    "dynbvh-render: render one frame with shadows, reflection and refraction to PNG.\n\n"
    "Usage: dynbvh-render [options]\n"
    "  --scene S        built-in name, .ply/.obj file, frame pattern or directory, BART .aff (default funnel)\n"
    "  --frame N        frame index (default 0)\n"
    "  --res WxH        image size (default 640x360)\n"
    "  --builder B      lbvh | kbvh | ploc | binned-sah | embree-low | ... (default ploc)\n"
    "  --effects E      auto (default): what the scene calls for; primary: primary rays and ambient/headlight only\n"
    "  --depth N        most reflection/refraction bounces (default 5)\n"
    "  --scale S        built-in scenes' triangle-count scale (default 1)\n"
    "  --threads N      worker threads (default all cores)\n"
    "  --backend B      tbb | omp | serial\n"
    "  --out FILE       PNG to write (default render.png)\n";

int parse_int(const std::string& opt, const std::string& v) {
    std::size_t used = 0;
    int x = 0;
    try {
        x = std::stoi(v, &used);
    } catch (const std::exception&) {
        used = 0;
    }
    if (used == 0 || used != v.size()) throw std::invalid_argument(opt + ": '" + v + "' is not an integer");
    return x;
}

} // namespace

int main(int argc, char** argv) {
    std::string scene_spec = "funnel", builder = "ploc", out = "render.png", backend_name, effects = "auto";
    int frame = 0, depth = 5, threads = 0;
    double scale = 1;
    study::Resolution res{640, 360};
    try {
        for (int i = 1; i < argc; ++i) {
            const std::string a = argv[i];
            auto val = [&]() -> std::string {
                if (i + 1 >= argc) throw std::invalid_argument(a + " needs a value");
                return argv[++i];
            };
            if (a == "--help" || a == "-h") {
                std::fputs(usage_text, stdout);
                return 0;
            } else if (a == "--scene") scene_spec = val();
            else if (a == "--frame") frame = parse_int(a, val());
            else if (a == "--res") res = study::parse_resolution(val());
            else if (a == "--builder") builder = val();
            else if (a == "--effects") effects = val();
            else if (a == "--depth") depth = parse_int(a, val());
            else if (a == "--scale") scale = std::stod(val());
            else if (a == "--threads") threads = parse_int(a, val());
            else if (a == "--backend") backend_name = val();
            else if (a == "--out") out = val();
            else throw std::invalid_argument("unknown option '" + a + "' (see --help)");
        }
        if (effects != "auto" && effects != "primary") throw std::invalid_argument("--effects must be auto or primary");
        if (depth < 0 || depth > 64) throw std::invalid_argument("--depth must be between 0 and 64");
        if (!(scale > 0 && scale <= 16)) throw std::invalid_argument("--scale must be in (0, 16]");
    } catch (const std::exception& e) {
        std::fprintf(stderr, "dynbvh-render: %s\n", e.what());
        return 2;
    }
    try {
        study::OpenedScene s = study::open_scene(scene_spec, {.scale = scale, .seed = 1});
        if (frame < 0 || std::size_t(frame) >= s.scene->frame_count())
            throw std::invalid_argument("--frame " + std::to_string(frame) + ": " + s.name + " has " +
                                        std::to_string(s.scene->frame_count()) + " frames");
        io::Frame f;
        s.scene->frame(std::size_t(frame), f);
        const study::Backend backend = study::Backend::make(backend_name, threads);
        auto accel = study::make_accel(study::parse_builder(builder), backend);
        accel->prepare(f.triangles);
        accel->build(f.triangles);

        render::Config cfg{.max_depth = depth};
        if (effects == "primary") cfg.shadows = cfg.reflections = cfg.refractions = false;
        render::Image img;
        const study::RayGen cam(f.camera, res.width, res.height);
        const render::Stats st = render::render(study::AccelTracer{*accel, f.triangles}, render::scene_view(f, *s.scene), cam,
                                                img, cfg, backend);
        study::write_linear_png(out, img.width, img.height, img.pixels);

        std::printf("%s frame %d, %zu triangles, %s, %s %d threads, %dx%d, depth %d\n", s.name.c_str(), frame, f.triangles.size(),
                    builder.c_str(), backend.name().c_str(), backend.threads(), res.width, res.height, depth);
        std::printf("%-11s %12s %10s %10s\n", "kind", "rays", "ms", "Mrays/s");
        for (render::RayKind k : render::ray_kinds) {
            const double ms = st.ms(k);
            std::printf("%-11s %12llu %10.2f %10.2f\n", render::to_string(k), static_cast<unsigned long long>(st.count(k)), ms,
                        ms > 0 ? double(st.count(k)) / ms / 1e3 : 0.0);
        }
        std::printf("shading %.2f ms, deepest bounce %d\nwrote %s\n", st.shade_ms, st.depth_reached, out.c_str());
        return 0;
    } catch (const std::exception& e) {
        std::fprintf(stderr, "dynbvh-render: error: %s\n", e.what());
        return 1;
    }
}
