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

/// Pixel offset of lane j in a packet of N rays: 8 = 4x2 pixels, 16 = 4x4, 32 = 8x4 as two 4x4
/// halves (lanes 0-15 left, 16-31 right, so each 16-lane SIMD step is a square).
constexpr int packet_dx(int j) noexcept { return j % 4 + 4 * (j / 16); }
constexpr int packet_dy(int j) noexcept { return (j / 4) % 4; }

/// The rays of tile `t` in packets of N = 8, 16 or 32 (packet_dx, packet_dy): f(rays, valid, x0, y0)
/// once per packet, lane j being pixel (x0 + packet_dx(j), y0 + packet_dy(j)); a lane past the tile's
/// edge has valid[j] == 0 and a copy of the packet's first ray. The one packet tiling of the study and
/// dynbvh-bench-trace.
template <int N, class F>
void for_each_packet(const RayGen& gen, const Tile& t, F&& f) {
    static_assert(N == 8 || N == 16 || N == 32, "packets of 8 (4x2), 16 (4x4) or 32 (8x4) rays");
    constexpr int pw = N == 32 ? 8 : 4, ph = N == 8 ? 2 : 4;
    Rayf rays[N];
    int valid[N];
    for (int y0 = t.y0; y0 < t.y1; y0 += ph)
        for (int x0 = t.x0; x0 < t.x1; x0 += pw) {
            for (int j = 0; j < N; ++j) {
                const int x = x0 + packet_dx(j), y = y0 + packet_dy(j);
                valid[j] = x < t.x1 && y < t.y1;
                rays[j] = gen.ray(valid[j] ? x : x0, valid[j] ? y : y0);
            }
            f(static_cast<const Rayf*>(rays), static_cast<const int*>(valid), x0, y0);
        }
}

} // namespace dynbvh::study
