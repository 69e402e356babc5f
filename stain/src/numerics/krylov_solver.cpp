// The Krylov solver's non-template pieces (releaseActive).
#include "numerics/krylov_solver.h"

namespace blot::stain::diffusion_internal {

void releaseActive(ActiveSet& active, std::initializer_list<double*> vectors) {
  const int* list = active.list();
  for (double* v : vectors) {
    for (int k = 0; k < active.size(); ++k) {
      v[2 * list[k]] = 0.0;
      v[2 * list[k] + 1] = 0.0;
    }
  }
  active.clearMarks();
}

}  // namespace blot::stain::diffusion_internal
