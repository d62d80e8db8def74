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

#include <cli.hpp>
#include <render/whitted.hpp>

#include "backend.hpp"
#include "builders.hpp"
#include "camera.hpp"
#include "image.hpp"
#include "options.hpp"
#include "scene_open.hpp"

using namespace dynbvh;

namespace {

const char* const description = "dynbvh-render: render one frame with shadows, reflection and refraction to PNG.";

} // namespace

int main(int argc, char** argv) {
    std::string scene_spec = "funnel", builder = "ploc", out = "render.png", backend_name, effects = "auto";
    int frame = 0, depth = 5, threads = 0;
    double scale = 1;
    study::Resolution res{640, 360};
    std::string res_text = "640x360";
    CLI::App app{description, "dynbvh-render"};
    cli::take_last(app);
    app.add_option("--scene", scene_spec, "built-in name, .ply/.obj file, frame pattern or directory, BART .aff (default funnel)")
        ->type_name("S");
    app.add_option("--frame", frame, "frame index (default 0)")->type_name("N")->check(cli::number_in(0, 1 << 30));
    app.add_option("--res", res_text, "image size (default 640x360)")->type_name("WxH");
    app.add_option("--builder", builder, "lbvh | kbvh | ploc | binned-sah | embree-low | ... (default ploc)")->type_name("B");
    app.add_option("--effects", effects, "auto (default): what the scene calls for; primary: primary rays and ambient/headlight only")
        ->check(CLI::IsMember({"auto", "primary"}))
        ->type_name("E");
    app.add_option("--depth", depth, "most reflection/refraction bounces (default 5)")->type_name("N")->check(cli::number_in(0, 64));
    app.add_option("--scale", scale, "built-in scenes' triangle-count scale, 0 < S <= 16 (default 1)")
        ->type_name("S")
        ->check(cli::number_in(0.0, 16.0));
    app.add_option("--threads", threads, "worker threads (default 0: all cores)")->type_name("N")->check(cli::number_in(0, 4096));
    app.add_option("--backend", backend_name, "tbb | omp | serial")->check(CLI::IsMember({"tbb", "omp", "serial"}))->type_name("B");
    app.add_option("--out", out, "PNG to write (default render.png)")->type_name("FILE");
    app.footer("Options take their value as --x V or --x=V.");
    if (const auto rc = cli::parse(app, argc, argv)) return *rc;
    try {
        res = study::parse_resolution(res_text);
        if (!(scale > 0)) throw std::invalid_argument("--scale must be in (0, 16]");
        if (out.empty()) throw std::invalid_argument("--out needs a file name");
    } catch (const std::exception& e) {
        std::fprintf(stderr, "dynbvh-render: %s (see --help)\n", e.what());
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
