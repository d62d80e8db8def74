// The host a study ran on: CPU model, cores, memory, compiler, date, Embree version.
#pragma once

#include "results.hpp"

namespace dynbvh::study {

MachineInfo machine_info();

} // namespace dynbvh::study
