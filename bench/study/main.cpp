// dynbvh-study: the thesis's study (build + trace per frame, FPS, SAH) on built-in or real scenes,
// side by side with Embree 3, plus what accuracy costs in time (--sweep). See --help.
#include <cstdio>
#include <exception>
#include <filesystem>
#include <iostream>

#include "backend.hpp"
#include "options.hpp"
#include "output.hpp"
#include "report.hpp"
#include "runner.hpp"
#include "scene_open.hpp"
#include "tables.hpp"

using namespace dynbvh::study;

int main(int argc, char** argv) {
    Options opt;
    try {
        opt = parse_options(argc, argv);
    } catch (const std::exception& e) {
        std::fprintf(stderr, "dynbvh-study: %s (see --help)\n", e.what());
        return 2;
    }
    if (opt.help) {
        std::fputs(usage().c_str(), stdout);
        return 0;
    }
    try {
        if (!opt.info.empty()) {
            OpenedScene s = open_scene(opt.info, {.scale = opt.scale, .seed = opt.seed});
            std::fputs(scene_info_json(s, opt.frames).c_str(), stdout);
            return 0;
        }
        const Backend backend = Backend::make(opt.backend, opt.threads);
        std::fprintf(stderr, "dynbvh-study: backend %s, %d thread%s, output in %s\n", backend.name().c_str(), backend.threads(),
                     backend.threads() == 1 ? "" : "s", opt.out.c_str());
        const StudyResults r = run_study(opt, backend);
        const std::filesystem::path out = opt.out;
        write_text((out / "study.json").string(), study_json(r));
        write_text((out / "study.csv").string(), study_csv(r));
        const std::string report = write_report(r);

        std::string text;
        if (!r.scenes.empty()) {
            text += '\n';
            text += render_text(scenes_table(r.scenes));
            text += '\n';
            for (const auto& t : study_tables(r)) text += render_text(t) + "\n";
            for (const auto& t : effects_tables(r)) text += render_text(t) + "\n";
            if (const auto fx = effects_conclusions(r); !fx.empty()) {
                text += "Effects\n";
                for (const auto& c : fx) text += "  - " + c + "\n";
                text += "\n";
            }
            text += "Conclusions\n";
            for (const auto& c : study_conclusions(r)) text += "  - " + c + "\n";
            text += "\n";
        }
        if (!r.sweep.empty()) {
            for (const auto& t : sweep_tables(r)) text += render_text(t) + "\n";
            text += "Sweep conclusions\n";
            for (const auto& c : sweep_conclusions(r)) text += "  - " + c + "\n";
            text += "\n";
        }
        for (const auto& s : r.skipped) text += "skipped: " + s.builder + " on " + s.scene + ": " + s.reason + "\n";
        std::fputs(text.c_str(), stdout);
        std::printf("\nReport: %s\nData:   %s, %s\nWall time: %.1f s\n", report.c_str(), (out / "study.json").string().c_str(),
                    (out / "study.csv").string().c_str(), r.wall_s);
        return 0;
    } catch (const std::exception& e) {
        std::fprintf(stderr, "\ndynbvh-study: error: %s\n", e.what());
        return 1;
    }
}
