// The one translation unit that compiles stb_image_write (Debian's libstb-dev header).
#define STB_IMAGE_WRITE_IMPLEMENTATION
#include <stb/stb_image_write.h>

#include <cstdint>
#include <string>

namespace dynbvh::study {

bool stb_write_png_rgb(const std::string& path, int width, int height, const std::uint8_t* rgb) {
    return stbi_write_png(path.c_str(), width, height, 3, rgb, width * 3) != 0;
}

} // namespace dynbvh::study
