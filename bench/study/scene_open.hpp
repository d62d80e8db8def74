// One entry point for every scene the study accepts: built-in names, PLY/OBJ files, frame
// patterns, directories of frames and BART .aff files; plus the --info description of a scene.
#pragma once

#include <memory>
#include <string>

#include <dynbvh/io/scene.hpp>

namespace dynbvh::study {

struct SceneOptions {
    double scale = 1.0;          ///< built-in scenes only
    std::uint64_t seed = 1;      ///< built-in scenes only
};

struct OpenedScene {
    std::unique_ptr<io::Scene> scene;
    std::string spec;            ///< as given
    std::string name;            ///< built-in name, or the scene's own name
    std::string kind;            ///< builtin | mesh | frames | bart
    std::string format;          ///< builtin | ply | obj | aff | mixed
    double scale = 1.0;          ///< built-in scenes: the scale used; files: 1
};

/// Opens `spec`: a built-in name, a .ply/.obj file (1 frame), a printf-style pattern or a directory
/// of .ply/.obj frames, or a BART .aff file. Throws io::LoadError (bad files) or
/// std::invalid_argument naming the spec (nothing by that name).
OpenedScene open_scene(const std::string& spec, const SceneOptions& opt);

/// One JSON object describing the scene (for --info): triangles, frames, bounds, motion,
/// topology_changes, materials, lights, format, mean vertex motion. Evaluates up to
/// `max_frames` frames (0: all).
std::string scene_info_json(OpenedScene& s, std::size_t max_frames);

} // namespace dynbvh::study
