// DynAccel on exec::tbb (see dyn_accel.hpp).
#include "dyn_accel.hpp"

#if defined(DYNBVH_WITH_TBB)
namespace dynbvh::study {
template std::unique_ptr<Accel> make_dyn_accel(const BuilderSpec&, const exec::tbb&, const Backend&);
}
#endif
