// DynAccel on exec::omp (see dyn_accel.hpp).
#include "dyn_accel.hpp"

#if defined(_OPENMP)
namespace dynbvh::study {
template std::unique_ptr<Accel> make_dyn_accel(const BuilderSpec&, const exec::omp&, const Backend&);
}
#endif
