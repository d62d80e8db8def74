// PNG renders of traced frames: the hit triangle's material colour shaded by the scene's lights
// (n.l, two-sided, no shadows) or by a headlight when the scene has none; misses are background.
#pragma once

#include <cstdint>
#include <span>
#include <string>
#include <vector>

#include <dynbvh/io/scene.hpp>

#include "camera.hpp"

namespace dynbvh::study {

/// Shades `prims` (one per pixel of `gen`, from tracing frame `f`) and writes an RGB PNG to `path`.
/// Returns the number of pixels that hit. Throws std::runtime_error when the file cannot be written.
std::size_t render_png(const std::string& path, const io::Frame& f, const io::SceneInfo& info, const RayGen& gen,
                       std::span<const std::uint32_t> prims);

/// Writes linear RGB pixels (rows top to bottom; e.g. a render::Image) as an sRGB PNG, values clamped
/// to [0, 1]. Throws std::runtime_error naming the file when it cannot be written.
void write_linear_png(const std::string& path, int width, int height, std::span<const Vec3f> linear);

/// Writes 8-bit RGB pixels (rows top to bottom) as PNG: stb_image_write when available, otherwise
/// our own encoder (stored deflate blocks: larger files, no dependency). Returns false on failure.
bool write_png(const std::string& path, int width, int height, std::span<const std::uint8_t> rgb);

/// The encoder used when stb is missing (exposed for tests): a complete PNG file in memory.
std::vector<std::uint8_t> encode_png_stored(int width, int height, std::span<const std::uint8_t> rgb);

} // namespace dynbvh::study
