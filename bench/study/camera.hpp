// Primary rays: one per pixel through the pixel's centre from the scene's pinhole camera,
// and the image split into square tiles that the tracing loop hands to the executor.
#pragma once

#include <cstddef>

#include <dynbvh/io/scene.hpp>
#include <dynbvh/ray.hpp>

namespace dynbvh::study {

struct Tile {
    int x0, y0, x1, y1;   ///< pixels [x0, x1) x [y0, y1)
};

class RayGen {
public:
    static constexpr int tile_size = 16;

    /// Camera `cam` (vertical field of view cam.fov_y_deg) on a width x height image; row 0 is the top.
    RayGen(const io::Camera& cam, int width, int height);

    /// The ray through the centre of pixel (x, y): origin at the eye, unnormalised direction, t in [0, inf).
    Rayf ray(int x, int y) const noexcept {
        const float sx = float(x) + 0.5f, sy = float(y) + 0.5f;
        Rayf r;
        r.org = eye_;
        r.dir = corner_ + du_ * sx + dv_ * sy;
        return r;
    }
    int width() const noexcept { return w_; }
    int height() const noexcept { return h_; }
    std::size_t tile_count() const noexcept { return std::size_t(tiles_x_) * std::size_t(tiles_y_); }
    Tile tile(std::size_t k) const noexcept {
        const int tx = int(k % std::size_t(tiles_x_)), ty = int(k / std::size_t(tiles_x_));
        const int x0 = tx * tile_size, y0 = ty * tile_size;
        return {x0, y0, x0 + tile_size < w_ ? x0 + tile_size : w_, y0 + tile_size < h_ ? y0 + tile_size : h_};
    }

private:
    int w_, h_, tiles_x_, tiles_y_;
    Vec3f eye_, corner_, du_, dv_;
};

} // namespace dynbvh::study
