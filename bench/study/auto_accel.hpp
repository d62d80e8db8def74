// AutoAccel and TwoLevelAccel: the study's `auto` and `two-level` strategies. AutoAccel: the `auto` strategy (dynbvh::Dynamic, dynamic.hpp: refit each frame, rebuild with
// PLOC or LBVH past an SAH threshold, optionally in the background) behind the Accel interface. It is
// traced like our other builders: the 4- or 8-wide tree converted from the policy's binary tree every
// frame (timed, as for every builder), through accel_impl::Trees (accel_trace.cpp). Instantiated once
// per executor in accel_auto.cpp.
#pragma once

#include <memory>

#include "builders.hpp"

namespace dynbvh::study {

/// The Accel for an `auto` spec (spec.kind == Kind::dynamic) on executor `ex`.
template <class Exec>
std::unique_ptr<Accel> make_auto_accel(const BuilderSpec& spec, const Exec& ex, const Backend& backend);

extern template std::unique_ptr<Accel> make_auto_accel(const BuilderSpec&, const exec::serial&, const Backend&);
#if defined(_OPENMP)
extern template std::unique_ptr<Accel> make_auto_accel(const BuilderSpec&, const exec::omp&, const Backend&);
#endif
#if defined(DYNBVH_WITH_TBB)
extern template std::unique_ptr<Accel> make_auto_accel(const BuilderSpec&, const exec::tbb&, const Backend&);
#endif

/// The Accel for a `two-level` spec (spec.kind == Kind::two_level) on executor `ex`: dynbvh::TwoLevel
/// over the frame's objects (Accel::frame_objects) grouped into bodies (object_groups.hpp: the static
/// objects together, the objects of one io::ObjectInstance::rigid_body together). Rigid bodies are built
/// once, in object space: their triangles are taken from the first frame through the inverse of that
/// frame's transform (the built-in scenes give world-space triangles only), and placed by each frame's
/// transform; animated objects whose transform is the identity (cloth) are deforming: refitted or
/// rebuilt by their own policy every frame. The top level is rebuilt every frame. A frame whose object
/// layout differs from the last (a fracture) sets the scene up again. Traced through the objects'
/// block trees (TwoLevel::intersect, one ray or a packet). Instantiated in accel_two_level.cpp.
template <class Exec>
std::unique_ptr<Accel> make_two_level_accel(const BuilderSpec& spec, const Exec& ex, const Backend& backend);

extern template std::unique_ptr<Accel> make_two_level_accel(const BuilderSpec&, const exec::serial&, const Backend&);
#if defined(_OPENMP)
extern template std::unique_ptr<Accel> make_two_level_accel(const BuilderSpec&, const exec::omp&, const Backend&);
#endif
#if defined(DYNBVH_WITH_TBB)
extern template std::unique_ptr<Accel> make_two_level_accel(const BuilderSpec&, const exec::tbb&, const Backend&);
#endif

} // namespace dynbvh::study
