// The thesis's own figures (../shared/STUDY.md: UTEC 2023, i7-9750H, 12 threads, madmann91/bvh),
// printed beside ours where a scene corresponds: cloth-ball ~ Cloth-ball, n-body ~ N-body,
// breaking ~ Dragon (bunny breaks a dragon), large-breaking ~ Lion.
#pragma once

#include <optional>
#include <string>
#include <string_view>

#include "results.hpp"

namespace dynbvh::study::thesis {

enum class Metric { fps, build_ms, trace_ms, sah };

/// Column of the thesis's tables for one of our scenes (-1: no counterpart). Real UNC files count too
/// (cloth_ball*.ply, balls16_*.ply).
inline int scene_column(std::string_view scene) {
    if (scene == "cloth-ball" || scene.find("cloth_ball") != std::string_view::npos) return 0;
    if (scene == "n-body" || scene.find("balls16") != std::string_view::npos) return 1;
    if (scene == "breaking") return 2;
    if (scene == "large-breaking") return 3;
    return -1;
}
/// The thesis's name of that scene.
inline const char* scene_name(int column) {
    static const char* names[] = {"Cloth-ball", "N-body", "Dragon", "Lion"};
    return column >= 0 && column < 4 ? names[column] : "";
}
/// Row for one of our builders (-1: the thesis did not run it). Only default settings count.
inline int builder_row(std::string_view builder) {
    if (builder == "lbvh") return 0;
    if (builder == "kbvh") return 1;
    if (builder == "ploc") return 2;
    return -1;
}

/// The thesis's mean-per-frame figure, when it published one for this metric, builder, scene and
/// resolution (build time and SAH do not depend on the resolution).
inline std::optional<double> value(Metric m, std::string_view builder, std::string_view scene, Resolution res) {
    static constexpr double build[3][4] = {{15, 25, 44, 304}, {205, 339, 595, 3417}, {76, 119, 230, 1605}};
    static constexpr double trace1080[3][4] = {{297, 972, 842, 2665}, {290, 1010, 850, 1155}, {287, 844, 720, 2235}};
    static constexpr double fps480[3][4] = {{12.99, 4.46, 4.66, 1.18}, {3.71, 1.80, 1.29, 0.27}, {7.19, 3.28, 2.56, 0.48}};
    static constexpr double fps2160[3][4] = {{0.856, 0.259, 0.302, 0.092}, {0.75, 0.234, 0.257, 0.126}, {0.838, 0.292, 0.327, 0.097}};
    static constexpr double sah[3][4] = {{99.72, 184.28, 83.02, 942.98}, {101.62, 197.78, 83.12, 560.55}, {86.56, 154.75, 68.25, 724.65}};
    const int b = builder_row(builder), s = scene_column(scene);
    if (b < 0 || s < 0) return std::nullopt;
    switch (m) {
        case Metric::build_ms: return build[b][s];
        case Metric::sah: return sah[b][s];
        case Metric::trace_ms:
            if (res == Resolution{1920, 1080}) return trace1080[b][s];
            return std::nullopt;
        case Metric::fps:
            if (res == Resolution{854, 480}) return fps480[b][s];
            if (res == Resolution{3840, 2160}) return fps2160[b][s];
            return std::nullopt;
    }
    return std::nullopt;
}

} // namespace dynbvh::study::thesis
