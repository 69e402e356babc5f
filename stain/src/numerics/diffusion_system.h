// The diffusion systems M + hL: the right-hand side M x shared with the stage
// (the assembly itself and DiffusionSystems::factorize are in diffusion_system.cpp).
#pragma once

#include <blot/stain/stages/diffusion.h>

namespace blot::stain::diffusion_internal {

// rhs_i = A_i x_i. Serial on purpose: one multiply per vertex is memory-bound
// and costs ~1 % of the solve it feeds; an OpenMP region costs more than it
// saves below ~10^5 vertices (and libgomp allocates on every region it starts).
template <typename Scalar>
void massTimes(const Vector& dualAreas, const Eigen::Matrix<Scalar, Eigen::Dynamic, 1>& x,
               Eigen::Matrix<Scalar, Eigen::Dynamic, 1>& rhs) {
  rhs = dualAreas.cast<Scalar>().cwiseProduct(x);
}

}  // namespace blot::stain::diffusion_internal
