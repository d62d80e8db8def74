/// @file render/material.hpp
/// How the Whitted renderer (render/whitted.hpp) reads an io::Material: which secondary rays a
/// surface asks for. The loaders only report what MTL/BART say; this reading is the renderer's.
#pragma once

#include <dynbvh/io/scene.hpp>

namespace dynbvh::render {

/// Mirror reflection: any specular channel > 0 (MTL Ks, BART ks) asks for reflection rays.
inline bool reflects(const io::Material& m) noexcept { return m.specular.x > 0 || m.specular.y > 0 || m.specular.z > 0; }

/// Refraction: transmission > 0 asks for refraction rays.
inline bool refracts(const io::Material& m) noexcept { return m.transmission > 0; }

} // namespace dynbvh::render
