#include <blot/coupling/liquid_exchange.h>

#include <blot/cloth/surface_motion.h>

#include <cmath>

namespace blot::coupling {

int exchangeMomentum(const Eigen::VectorXd& startMasses, const Eigen::VectorXd& endMasses,
                     const Eigen::MatrixX3d& startRelative, const Eigen::MatrixX3d& endRelative,
                     const Eigen::MatrixX3d& nodeVelocities, const Eigen::VectorXd& evaporatedMass,
                     Eigen::MatrixX3d& impulses, Eigen::Vector3d& vapourMomentum) {
  int bad = -1;
  for (Eigen::Index i = 0; i < endMasses.size(); ++i) {
    const double vapour = evaporatedMass[i];
    const Eigen::Vector3d vi = nodeVelocities.row(i).transpose();
    const Eigen::Vector3d change =
        (endMasses[i] - startMasses[i]) * vi + (endRelative.row(i) - startRelative.row(i)).transpose();
    impulses.row(i) = (-change - vapour * vi).transpose();
    vapourMomentum += vapour * vi;
    const bool loadable = impulses.row(i).allFinite() && impulses.row(i).cwiseAbs().maxCoeff() <= cloth::kMaxLiquidLoad &&
                          std::isfinite(endMasses[i]) && endMasses[i] <= cloth::kMaxLiquidLoad;
    if (bad < 0 && !loadable) bad = static_cast<int>(i);
  }
  return bad;
}

}  // namespace blot::coupling
