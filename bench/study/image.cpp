#include "image.hpp"

#include <algorithm>
#include <array>
#include <cmath>
#include <fstream>
#include <stdexcept>

#include <dynbvh/ray.hpp>

namespace dynbvh::study {

#if defined(DYNBVH_STUDY_STB)
bool stb_write_png_rgb(const std::string& path, int width, int height, const std::uint8_t* rgb);   // stb_write.cpp
#endif

namespace {

std::uint32_t crc32(const std::uint8_t* p, std::size_t n, std::uint32_t crc = 0) {
    static const std::array<std::uint32_t, 256> table = [] {
        std::array<std::uint32_t, 256> t{};
        for (std::uint32_t i = 0; i < 256; ++i) {
            std::uint32_t c = i;
            for (int k = 0; k < 8; ++k) c = (c & 1) ? 0xEDB88320u ^ (c >> 1) : c >> 1;
            t[i] = c;
        }
        return t;
    }();
    crc = ~crc;
    for (std::size_t i = 0; i < n; ++i) crc = table[(crc ^ p[i]) & 0xFF] ^ (crc >> 8);
    return ~crc;
}

void put32(std::vector<std::uint8_t>& o, std::uint32_t v) {
    o.push_back(std::uint8_t(v >> 24));
    o.push_back(std::uint8_t(v >> 16));
    o.push_back(std::uint8_t(v >> 8));
    o.push_back(std::uint8_t(v));
}

void chunk(std::vector<std::uint8_t>& o, const char* type, const std::vector<std::uint8_t>& data) {
    put32(o, std::uint32_t(data.size()));
    const std::size_t start = o.size();
    o.insert(o.end(), type, type + 4);
    o.insert(o.end(), data.begin(), data.end());
    put32(o, crc32(o.data() + start, o.size() - start));
}

float to_srgb(float linear) {
    const float c = std::clamp(linear, 0.0f, 1.0f);
    return c <= 0.0031308f ? 12.92f * c : 1.055f * std::pow(c, 1 / 2.4f) - 0.055f;
}

} // namespace

std::vector<std::uint8_t> encode_png_stored(int width, int height, std::span<const std::uint8_t> rgb) {
    // Raw scanlines, each prefixed by filter type 0.
    const std::size_t row = std::size_t(width) * 3;
    std::vector<std::uint8_t> raw;
    raw.reserve((row + 1) * std::size_t(height));
    for (int y = 0; y < height; ++y) {
        raw.push_back(0);
        const auto* r = rgb.data() + std::size_t(y) * row;
        raw.insert(raw.end(), r, r + row);
    }
    // zlib stream of stored blocks (at most 65535 bytes each), then Adler-32.
    std::vector<std::uint8_t> z{0x78, 0x01};
    std::size_t pos = 0;
    do {
        const std::size_t n = std::min<std::size_t>(65535, raw.size() - pos);
        const bool last = pos + n == raw.size();
        z.push_back(last ? 1 : 0);
        z.push_back(std::uint8_t(n & 0xFF));
        z.push_back(std::uint8_t(n >> 8));
        z.push_back(std::uint8_t(~n & 0xFF));
        z.push_back(std::uint8_t((~n >> 8) & 0xFF));
        z.insert(z.end(), raw.begin() + std::ptrdiff_t(pos), raw.begin() + std::ptrdiff_t(pos + n));
        pos += n;
    } while (pos < raw.size());
    std::uint32_t a = 1, b = 0;
    for (std::uint8_t c : raw) {
        a = (a + c) % 65521;
        b = (b + a) % 65521;
    }
    put32(z, (b << 16) | a);

    std::vector<std::uint8_t> png{0x89, 'P', 'N', 'G', '\r', '\n', 0x1A, '\n'};
    std::vector<std::uint8_t> ihdr;
    put32(ihdr, std::uint32_t(width));
    put32(ihdr, std::uint32_t(height));
    ihdr.insert(ihdr.end(), {8, 2, 0, 0, 0});   // 8-bit, RGB, deflate, no filter method, no interlace
    chunk(png, "IHDR", ihdr);
    chunk(png, "IDAT", z);
    chunk(png, "IEND", {});
    return png;
}

bool write_png(const std::string& path, int width, int height, std::span<const std::uint8_t> rgb) {
    if (width <= 0 || height <= 0 || rgb.size() < std::size_t(width) * std::size_t(height) * 3) return false;
#if defined(DYNBVH_STUDY_STB)
    return stb_write_png_rgb(path, width, height, rgb.data());
#else
    const auto png = encode_png_stored(width, height, rgb);
    std::ofstream out(path, std::ios::binary | std::ios::trunc);
    out.write(reinterpret_cast<const char*>(png.data()), std::streamsize(png.size()));
    return bool(out);
#endif
}

void write_linear_png(const std::string& path, int width, int height, std::span<const Vec3f> linear) {
    const std::size_t n = std::size_t(std::max(0, width)) * std::size_t(std::max(0, height));
    std::vector<std::uint8_t> rgb(3 * n);
    for (std::size_t i = 0; i < n && i < linear.size(); ++i) {
        rgb[3 * i + 0] = std::uint8_t(std::lround(255 * to_srgb(linear[i].x)));
        rgb[3 * i + 1] = std::uint8_t(std::lround(255 * to_srgb(linear[i].y)));
        rgb[3 * i + 2] = std::uint8_t(std::lround(255 * to_srgb(linear[i].z)));
    }
    if (linear.size() < n || !write_png(path, width, height, rgb)) throw std::runtime_error("cannot write image " + path);
}

std::size_t render_png(const std::string& path, const io::Frame& f, const io::SceneInfo& info, const RayGen& gen,
                       std::span<const std::uint32_t> prims) {
    const int w = gen.width(), h = gen.height();
    std::vector<std::uint8_t> rgb(std::size_t(w) * std::size_t(h) * 3);
    std::size_t hits = 0;
    const std::size_t nl = std::min<std::size_t>(info.lights.size(), 4);
    for (int y = 0; y < h; ++y) {
        for (int x = 0; x < w; ++x) {
            const std::size_t i = std::size_t(y) * std::size_t(w) + std::size_t(x);
            Vec3f c;
            const std::uint32_t p = prims[i];
            if (p != invalid_prim && p < f.triangles.size()) {
                ++hits;
                const Rayf ray = gen.ray(x, y);
                const Vec3f d = normalize(ray.dir);
                const Trianglef& t = f.triangles[p];
                Vec3f n = t.normal();
                const float nlen = length(n);
                n = nlen > 0 ? n * (1 / nlen) : Vec3f{0, 1, 0};
                if (dot(n, d) > 0) n = -n;   // two-sided: face the viewer
                const float denom = dot(n, d);
                const float th = denom != 0 ? dot(n, t.p0 - ray.org) / denom : 0;
                const Vec3f hit = ray.org + d * th;
                Vec3f albedo{0.8f, 0.8f, 0.8f};
                float transmission = 0;
                const std::uint32_t m = p < f.material.size() ? f.material[p] : 0;
                if (m < info.materials.size()) {
                    albedo = info.materials[m].diffuse;
                    transmission = info.materials[m].transmission;
                    if (albedo.x + albedo.y + albedo.z < 0.05f) albedo = {0.6f, 0.6f, 0.65f};   // mirrors and glass: show the shape
                }
                float light = 0;
                if (nl == 0) {
                    light = std::abs(dot(n, d));
                } else {
                    for (std::size_t k = 0; k < nl; ++k) {
                        const Vec3f l = info.lights[k].position - hit;
                        const float ll = length(l);
                        if (ll > 0) light += std::max(0.0f, dot(n, l * (1 / ll)));
                    }
                    light /= float(nl);
                    light = 0.7f * light + 0.3f * std::abs(dot(n, d));
                }
                const float shade = 0.12f + 0.88f * light;
                c = albedo * shade;
                if (transmission > 0) c = c * (1 - 0.5f * transmission) + Vec3f{0.55f, 0.7f, 0.8f} * (0.5f * transmission);
            } else {
                const float s = float(y) / float(std::max(1, h - 1));
                c = Vec3f{0.02f, 0.03f, 0.06f} * (1 - s) + Vec3f{0.12f, 0.13f, 0.16f} * s;
            }
            rgb[3 * i + 0] = std::uint8_t(std::lround(255 * to_srgb(c.x)));
            rgb[3 * i + 1] = std::uint8_t(std::lround(255 * to_srgb(c.y)));
            rgb[3 * i + 2] = std::uint8_t(std::lround(255 * to_srgb(c.z)));
        }
    }
    if (!write_png(path, w, h, rgb)) throw std::runtime_error("cannot write image " + path);
    return hits;
}

} // namespace dynbvh::study
