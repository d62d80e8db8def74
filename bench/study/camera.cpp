#include "camera.hpp"

#include <cmath>

namespace dynbvh::study {

RayGen::RayGen(const io::Camera& cam, int width, int height)
    : w_(width), h_(height), tiles_x_((width + tile_size - 1) / tile_size), tiles_y_((height + tile_size - 1) / tile_size) {
    eye_ = cam.from;
    Vec3f fwd = cam.at - cam.from;
    if (!(length(fwd) > 0) || !is_finite(fwd)) fwd = {0, 0, -1};
    fwd = normalize(fwd);
    Vec3f up = cam.up;
    Vec3f right = cross(fwd, up);
    if (!(length(right) > 1e-6f * (length(up) + 1e-30f))) {   // up parallel to the view direction: pick another
        up = std::abs(fwd.y) < 0.9f ? Vec3f{0, 1, 0} : Vec3f{1, 0, 0};
        right = cross(fwd, up);
    }
    right = normalize(right);
    const Vec3f upv = cross(right, fwd);
    float fov = cam.fov_y_deg;
    if (!(fov > 0.1f && fov < 179.0f)) fov = 45;
    const float half_h = std::tan(0.5f * fov * 3.14159265358979f / 180.0f);
    const float half_w = half_h * float(width) / float(height);
    // dir(x, y) = fwd + right * half_w * (2 sx / w - 1) + upv * half_h * (1 - 2 sy / h)
    du_ = right * (2 * half_w / float(width));
    dv_ = upv * (-2 * half_h / float(height));
    corner_ = fwd - right * half_w + upv * half_h;
}

} // namespace dynbvh::study
