// Liquid node masses and momentum sums for the two-way coupling.
//
// Design note: the liquid mass uses the same lumped mass (one third of the
// one-ring area) as the stain's finite-volume densities, so the mass handed to
// the cloth equals the mass the stain conserves, to rounding. A consistent
// (non-diagonal) mass matrix would smear mass onto dry neighbours.
#include <blot/coupling/liquid_mass.h>

#include <cmath>
#include <stdexcept>
#include <string>

namespace blot::coupling {

void liquidNodeMasses(const Eigen::VectorXd& vertexDualAreas, const Eigen::MatrixXd& surfaceDensities,
                      Eigen::VectorXd& nodeMasses) {
  const Eigen::Index n = vertexDualAreas.size();
  if (surfaceDensities.rows() != n)
    throw std::invalid_argument("liquidNodeMasses: " + std::to_string(surfaceDensities.rows()) +
                                " density rows for " + std::to_string(n) + " vertices");
  if (nodeMasses.size() != n) nodeMasses.resize(n);
  for (Eigen::Index i = 0; i < n; ++i) {
    double sum = 0;
    for (Eigen::Index c = 0; c < surfaceDensities.cols(); ++c) {
      const double s = surfaceDensities(i, c);
      if (!std::isfinite(s) || s < 0)
        throw std::invalid_argument("liquidNodeMasses: vertex " + std::to_string(i) + " component " +
                                    std::to_string(c) + " has density " + std::to_string(s) +
                                    " (expected finite and >= 0)");
      sum += s;
    }
    nodeMasses[i] = vertexDualAreas[i] * sum;
  }
}

Eigen::Vector3d totalMomentum(const Eigen::VectorXd& nodeMasses, const Eigen::MatrixX3d& velocities) {
  if (velocities.rows() != nodeMasses.size())
    throw std::invalid_argument("totalMomentum: velocity rows differ from node count");
  Eigen::Vector3d p = Eigen::Vector3d::Zero();
  for (Eigen::Index i = 0; i < nodeMasses.size(); ++i) p += nodeMasses[i] * velocities.row(i).transpose();
  return p;
}

}  // namespace blot::coupling
