// Static and analytic rigid surface motions.
//
// Design note: rigid positions are evaluated in closed form at each time (not
// integrated), so a long run has no drift and the edge lengths stay those of
// the rest shape to rounding: the stain solver then never refactorizes.
#include <blot/cloth/surface_motion.h>

#include <cmath>
#include <stdexcept>
#include <string>
#include <utility>

namespace blot::cloth {

bool massesWithinLoadLimit(const Eigen::VectorXd& masses) {
  return masses.allFinite() && (masses.size() == 0 || (masses.minCoeff() >= 0 && masses.maxCoeff() <= kMaxLiquidLoad));
}

bool impulsesWithinLoadLimit(const Eigen::MatrixX3d& impulses) {
  return impulses.allFinite() && (impulses.size() == 0 || impulses.cwiseAbs().maxCoeff() <= kMaxLiquidLoad);
}

void SurfaceMotion::setLiquidLoads(const Eigen::VectorXd&, const Eigen::MatrixX3d&) {
  throw std::logic_error("this surface motion is prescribed and takes no liquid loads (two-way coupling needs a simulated cloth)");
}

void SurfaceMotion::setPinTarget(int, const Eigen::Vector3d&) {
  throw std::invalid_argument("this surface motion has no pins (they belong to a Bullet cloth)");
}

void SurfaceMotion::setNextFrame(const Eigen::MatrixX3d&, const Eigen::MatrixX3d*) {
  throw std::invalid_argument("this surface motion takes no frames (they are given to a caller-supplied surface)");
}

void SurfaceMotion::setNextFrame(const double*, const double*) {
  throw std::invalid_argument("this surface motion takes no frames (they are given to a caller-supplied surface)");
}

StaticSurface::StaticSurface(const Eigen::MatrixX3d& restPositions)
    : positions_(restPositions), velocities_(Eigen::MatrixX3d::Zero(restPositions.rows(), 3)) {}

void StaticSurface::advance(double h) {
  if (!(h > 0)) throw std::invalid_argument("StaticSurface::advance: time step must be positive");
  time_ += h;
}

CallerMotion::CallerMotion(const Eigen::MatrixX3d& restPositions, const Eigen::MatrixX3d& initialVelocities)
    : positions_(restPositions),
      velocities_(initialVelocities.rows() > 0 ? initialVelocities : Eigen::MatrixX3d::Zero(restPositions.rows(), 3)),
      nextPositions_(restPositions),
      nextVelocities_(velocities_) {
  if (velocities_.rows() != positions_.rows())
    throw std::invalid_argument("CallerMotion: " + std::to_string(initialVelocities.rows()) +
                                " initial velocities for " + std::to_string(positions_.rows()) + " vertices");
  if (!positions_.allFinite() || !velocities_.allFinite())
    throw std::invalid_argument("CallerMotion: initial positions and velocities must be finite");
  keepRollbackPoint();
}

void CallerMotion::checkNext() {
  if (!nextPositions_.allFinite() || (nextHasVelocities_ && !nextVelocities_.allFinite())) {
    hasNext_ = false;
    throw std::invalid_argument("CallerMotion::setNextFrame: positions and velocities must be finite");
  }
  // Held to a scene's magnitudes (1e6): 1e300 m made the step fail as a
  // collapsed face ("area 0") instead of naming the frame.
  if (!(nextPositions_.cwiseAbs().maxCoeff() <= kMaxFrameMagnitude) ||
      (nextHasVelocities_ && !(nextVelocities_.cwiseAbs().maxCoeff() <= kMaxFrameMagnitude))) {
    hasNext_ = false;
    throw std::invalid_argument("CallerMotion::setNextFrame: positions (m) and velocities (m/s) must be at most 1e6 "
                                "in size, as a scene's");
  }
  hasNext_ = true;
}

void CallerMotion::setNextFrame(const Eigen::MatrixX3d& positions, const Eigen::MatrixX3d* velocities) {
  if (positions.rows() != positions_.rows() || (velocities && velocities->rows() != positions_.rows()))
    throw std::invalid_argument("CallerMotion::setNextFrame: expected " + std::to_string(positions_.rows()) +
                                " rows, got " + std::to_string(positions.rows()) + " positions" +
                                (velocities ? " and " + std::to_string(velocities->rows()) + " velocities" : ""));
  nextPositions_ = positions;
  nextHasVelocities_ = velocities != nullptr;
  if (velocities) nextVelocities_ = *velocities;
  checkNext();
}

void CallerMotion::setNextFrame(const double* positions, const double* velocities) {
  if (!positions) throw std::invalid_argument("CallerMotion::setNextFrame: positions must not be null");
  const Eigen::Index n = positions_.rows();
  using RowMajor = Eigen::Matrix<double, Eigen::Dynamic, 3, Eigen::RowMajor>;
  nextPositions_ = Eigen::Map<const RowMajor>(positions, n, 3);
  nextHasVelocities_ = velocities != nullptr;
  if (velocities) nextVelocities_ = Eigen::Map<const RowMajor>(velocities, n, 3);
  checkNext();
}

void CallerMotion::advance(double h) {
  if (!(h > 0) || !std::isfinite(h)) throw std::invalid_argument("CallerMotion::advance: time step must be positive");
  time_ += h;
  if (!hasNext_) {
    velocities_.setZero();
    return;
  }
  if (nextHasVelocities_) {
    velocities_ = nextVelocities_;
  } else {
    velocities_ = (nextPositions_ - positions_) / h;
  }
  positions_ = nextPositions_;
  hasNext_ = false;
}

void CallerMotion::keepRollbackPoint() {
  keptPositions_ = positions_;
  keptVelocities_ = velocities_;
  keptNextPositions_ = nextPositions_;
  keptNextVelocities_ = nextVelocities_;
  keptHasNext_ = hasNext_;
  keptNextHasVelocities_ = nextHasVelocities_;
  keptTime_ = time_;
}

void CallerMotion::rollBack() {
  positions_ = keptPositions_;
  velocities_ = keptVelocities_;
  nextPositions_ = keptNextPositions_;
  nextVelocities_ = keptNextVelocities_;
  hasNext_ = keptHasNext_;
  nextHasVelocities_ = keptNextHasVelocities_;
  time_ = keptTime_;
}

void CallerMotion::saveDynamicState(MotionStateVisitor& visitor) const {
  // The visitor takes non-const references: a saving visitor only reads
  // them, so loading a copy through it hands over every field unchanged.
  CallerMotion copy = *this;
  copy.loadDynamicState(visitor);
}

void CallerMotion::loadDynamicState(MotionStateVisitor& visitor) {
  const Eigen::Index n = positions_.rows();
  double time = time_;
  Eigen::MatrixX3d positions = positions_, velocities = velocities_, next = nextPositions_,
                   nextVelocities = nextVelocities_;
  bool hasNext = hasNext_, nextHasVelocities = nextHasVelocities_;
  visitor.field("time", time);
  visitor.field("positions", positions);
  visitor.field("velocities", velocities);
  visitor.field("nextPositions", next);
  visitor.field("nextVelocities", nextVelocities);
  visitor.field("hasNext", hasNext);
  visitor.field("nextHasVelocities", nextHasVelocities);
  if (positions.rows() != n || velocities.rows() != n || next.rows() != n || nextVelocities.rows() != n)
    throw std::invalid_argument("CallerMotion: state arrays have other row counts than the " + std::to_string(n) +
                                " vertices");
  if (!std::isfinite(time) || !positions.allFinite() || !velocities.allFinite() || !next.allFinite() ||
      !nextVelocities.allFinite())
    throw std::invalid_argument("CallerMotion: state values must be finite");
  time_ = time;
  positions_ = std::move(positions);
  velocities_ = std::move(velocities);
  nextPositions_ = std::move(next);
  nextVelocities_ = std::move(nextVelocities);
  hasNext_ = hasNext;
  nextHasVelocities_ = nextHasVelocities;
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

bool RigidMotion::positionsBefore(double h, Eigen::MatrixX3d& out) const {
  if (def_.angularVelocity.isZero(0.0) && def_.linearAcceleration.isZero(0.0)) return false;
  const double t = time_ - h;
  const Eigen::Matrix3d R = rotationAt(t);
  const Eigen::Vector3d c = pivotAt(t);
  out.resize(rest_.rows(), 3);
  for (Eigen::Index i = 0; i < rest_.rows(); ++i)
    out.row(i) = (c + R * (rest_.row(i).transpose() - def_.pivot)).transpose();
  return true;
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
