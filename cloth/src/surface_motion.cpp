// Static and analytic rigid surface motions.
//
// Design note: rigid positions are evaluated in closed form at each time (not
// integrated), so a long run has no drift and the edge lengths stay those of
// the rest shape to rounding: the stain solver then never refactorizes.
#include <blot/cloth/surface_motion.h>

#include <stdexcept>

namespace blot::cloth {

void SurfaceMotion::setLiquidLoads(const Eigen::VectorXd&, const Eigen::MatrixX3d&) {
  throw std::logic_error("this surface motion is prescribed and takes no liquid loads (two-way coupling needs a simulated cloth)");
}

StaticSurface::StaticSurface(const Eigen::MatrixX3d& restPositions)
    : positions_(restPositions), velocities_(Eigen::MatrixX3d::Zero(restPositions.rows(), 3)) {}

void StaticSurface::advance(double h) {
  if (!(h > 0)) throw std::invalid_argument("StaticSurface::advance: time step must be positive");
  time_ += h;
}

RigidMotion::RigidMotion(const Eigen::MatrixX3d& restPositions, const RigidMotionDef& def)
    : rest_(restPositions), def_(def) {
  if (!def.angularVelocity.allFinite() || !def.pivot.allFinite() || !def.linearVelocity.allFinite() ||
      !def.linearAcceleration.allFinite())
    throw std::invalid_argument("RigidMotion: non-finite motion parameter");
  evaluate();
}

Eigen::Matrix3d RigidMotion::rotationAt(double t) const {
  const double speed = def_.angularVelocity.norm();
  if (speed == 0) return Eigen::Matrix3d::Identity();
  return Eigen::AngleAxisd(speed * t, def_.angularVelocity / speed).toRotationMatrix();
}

Eigen::Vector3d RigidMotion::pivotAt(double t) const {
  return def_.pivot + def_.linearVelocity * t + 0.5 * def_.linearAcceleration * t * t;
}

void RigidMotion::advance(double h) {
  if (!(h > 0)) throw std::invalid_argument("RigidMotion::advance: time step must be positive");
  time_ += h;
  evaluate();
}

void RigidMotion::rollBack() {
  time_ = rollbackTime_;
  evaluate();
}

void RigidMotion::evaluate() {
  const Eigen::Matrix3d R = rotationAt(time_);
  const Eigen::Vector3d c = pivotAt(time_);
  const Eigen::Vector3d cDot = def_.linearVelocity + def_.linearAcceleration * time_;
  positions_.resize(rest_.rows(), 3);
  velocities_.resize(rest_.rows(), 3);
  for (Eigen::Index i = 0; i < rest_.rows(); ++i) {
    const Eigen::Vector3d r = R * (rest_.row(i).transpose() - def_.pivot);
    positions_.row(i) = (c + r).transpose();
    velocities_.row(i) = (cDot + def_.angularVelocity.cross(r)).transpose();
  }
}

}  // namespace blot::cloth
