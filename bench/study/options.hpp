// Command-line options of dynbvh-study and their parsing.
#pragma once

#include <cstdint>
#include <string>
#include <vector>

#include "results.hpp"

namespace dynbvh::study {

struct Options {
    std::vector<std::string> scenes;          ///< built-in names, files, patterns, directories, .aff; empty: every built-in
    std::vector<std::string> builders;        ///< builder specs (see builders.hpp); empty: every available builder
    std::vector<Resolution> resolutions{{854, 480}, {1920, 1080}, {3840, 2160}};
    int reps = 1;                             ///< repetitions of every scene x builder x resolution
    std::size_t frames = 0;                   ///< most frames per scene (0: all)
    std::size_t frame_step = 1;               ///< use every k-th frame; 0: spread `frames` evenly over the animation
    int threads = 0;                          ///< 0: every core
    std::string backend;                      ///< omp, tbb or serial; empty: Backend::default_name() (tbb when compiled in)
    std::string out = "out/study";
    double scale = 1.0;                       ///< built-in scenes' triangle-count scale
    std::uint64_t seed = 1;                   ///< built-in scenes' seed
    std::size_t images = 3;                   ///< frames rendered to PNG per scene
    std::size_t cache_mb = 2048;              ///< keep generated frames in memory up to this size
    bool sweep = false;                       ///< run the accuracy/time sweep after the study
    bool sweep_only = false;                  ///< run only the sweep
    std::vector<std::string> sweep_scenes;    ///< scenes of the sweep; empty: the study's scenes
    bool sweep_small = false;                 ///< fewer sweep settings (used by --quick)
    int sweep_reps = 0;                       ///< repetitions of the sweep (0: --reps)
    bool quick = false, full = false;
    bool effects = false;                     ///< --effects auto: also render shadows, reflections and refractions where the scene calls for them
    int effects_depth = 5;                    ///< --effects-depth: most reflection/refraction bounces (render::Config::max_depth)
    bool packets = true;                      ///< --rays packet (default): primary rays in packets of 16 (4x4 pixels); single: one at a time
    bool warmup = true;                       ///< one untimed build + trace per builder before the timed runs
    std::string info;                         ///< --info SPEC: print the scene's description and exit
    bool help = false;
    std::string command_line;                 ///< as typed, for the report
};

/// Parses argv. Throws std::invalid_argument with a message naming the bad option.
Options parse_options(int argc, char** argv);

/// The --help text.
std::string usage();

/// "854x480" -> {854, 480}; throws std::invalid_argument.
Resolution parse_resolution(const std::string& s);

/// Splits "a,b,c" (empty items dropped).
std::vector<std::string> split_list(const std::string& s, char sep = ',');

} // namespace dynbvh::study
