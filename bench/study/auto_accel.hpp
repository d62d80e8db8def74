// AutoAccel: the study's `auto` strategy (dynbvh::Dynamic, dynamic.hpp: refit each frame, rebuild with
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

} // namespace dynbvh::study
