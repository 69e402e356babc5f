// limitPositivity, the public entry to the positivity limiter on a topology's one-rings.
#include "numerics/positivity_limiter.h"

namespace blot::stain {
using namespace diffusion_internal;

std::pair<int, double> limitPositivity(const SurfaceTopology& topology, const Vector& dualAreas,
                                       Vector& densities) {
  return limit(TopologyRings{topology}, dualAreas, densities);
}

}  // namespace blot::stain
