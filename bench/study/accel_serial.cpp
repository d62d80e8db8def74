// DynAccel on exec::serial (see dyn_accel.hpp).
#include "dyn_accel.hpp"

namespace dynbvh::study {
template std::unique_ptr<Accel> make_dyn_accel(const BuilderSpec&, const exec::serial&, const Backend&);
}
