#pragma once
// The experiments shared by the accuracy and stability studies
// (tests/studies/*_study_test.cpp), each one function of its setup:
//
//  - runRigidRotationAdvection: a smooth blob carried once around by the
//    steady rigid rotation field u = ω ẑ × (x − c) on a static flat mesh, by
//    the library's sub-stepped upwind (advectDensities), the same with its
//    sub-step cap set to 1, or the naive un-limited upwind of study_support.h.
//    The exact answer is the initial blob rotated by ω t.
//  - runRotatingDisc: paper Fig. 5 through the whole StainSolver: a disc
//    rotating at ω about its axis, liquid moving in a straight line at constant
//    velocity in the inertial frame (relative velocity v0 − ω × x), diffusion
//    and interaction off; the centroid must follow x0 + v0 t, and for v0 = 0
//    the kinetic energy in the disc frame, Σ ½ A σ |u|², must stay constant.
#include <blot/stain/stages/density_advection.h>
#include <blot/stain/geometry/mesh_primitives.h>
#include <blot/stain/stain_solver.h>

#include <cmath>
#include <string>
#include <vector>

#include "stain_fixture.h"
#include "study_support.h"

namespace blot::test {

enum class AdvectionMethod { Ours, CapOne, Naive };

inline const char* toString(AdvectionMethod m) {
  switch (m) {
    case AdvectionMethod::Ours: return "ours (sub-stepped upwind)";
    case AdvectionMethod::CapOne: return "one sub-step (cap 1)";
    case AdvectionMethod::Naive: return "naive upwind (no sub-steps or limit)";
  }
  return "?";
}

struct RotationAdvectionSetup {
  double omega = 6.283185307179586;  ///< rad/s
  double h = 0.01;                   ///< s
  int steps = 100;
  stain::Vector2 center{0, 0};       ///< rotation centre (m)
  stain::Vector2 blobCenter{0.5, 0}; ///< m
  double blobRadius = 0.25;          ///< support radius of the (1 − r²)² bump (m)
  AdvectionMethod method = AdvectionMethod::Ours;
};

struct RotationAdvectionResult {
  double shapeError = 0;  ///< ‖σ − σ_exact‖_M / ‖σ_exact‖_M at the end
  double massError = 0;   ///< |Σ Aσ − Σ Aσ0| / Σ Aσ0
  FieldHealth health;
  double msPerStep = 0;
  double substepsPerStep = 0;
  int vertices = 0;
};

inline double bump(const stain::Vector2& x, const stain::Vector2& center, double radius) {
  const double r2 = (x - center).squaredNorm() / (radius * radius);
  return r2 < 1 ? (1 - r2) * (1 - r2) : 0.0;
}

/// Runs the advection on `g` (a flat mesh in z = 0 with its geometry).
inline RotationAdvectionResult runRigidRotationAdvection(const stain::liquid_testing::LiquidMesh& g,
                                                         const RotationAdvectionSetup& s) {
  using namespace stain;
  const int n = g.vertexCount();
  StainState state = liquid_testing::zeroState(n);
  Eigen::MatrixX2d velocity(n, 2);
  for (int i = 0; i < n; ++i) {
    const Vector2 x = g.position(i).head<2>();
    const Vector2 u = s.omega * Vector2(-(x.y() - s.center.y()), x.x() - s.center.x());
    velocity.row(i) = u.transpose();
    const Matrix3& frame = g.extrinsic.frames[static_cast<size_t>(i)];
    const Vector3 u3(u.x(), u.y(), 0);
    state.velocities[i] = Complex(frame.col(0).dot(u3), frame.col(1).dot(u3));
    state.solvent[i] = bump(x, s.blobCenter, s.blobRadius);
  }
  const Vector initial = state.solvent;
  const double mass0 = liquid_testing::totalMass(g.areas(), initial);
  const double max0 = initial.maxCoeff();

  PhysicsSwitches switches;
  StepContext ctx = makeStepContext(s.h, Vector3(0, 0, -9.8), switches, LiquidParameters{});
  if (s.method == AdvectionMethod::CapOne) ctx.maxAdvectionSubsteps = 1;
  DensityAdvectionScratch scratch;
  scratch.resize(n, g.topology.edgeCount(), g.topology.faceCount());
  const Eigen::MatrixX2d normals = barycentricDualNormals(g.topology, g.mesh.vertexPositions);
  const std::vector<char> all;  // empty: every vertex

  RotationAdvectionResult result;
  result.vertices = n;
  long substeps = 0;
  double ms = 0;
  for (int k = 0; k < s.steps; ++k) {
    const Stopwatch clock;
    if (s.method == AdvectionMethod::Naive) {
      naiveUpwindStep(g.topology, normals, g.areas(), velocity, s.h, state.solvent);
      substeps += 1;
    } else {
      substeps += advectDensities(ctx, g.topology, g.intrinsic, g.extrinsic, all, scratch, state).substeps;
    }
    ms += clock.milliseconds();
    if (!state.solvent.allFinite()) break;
  }
  result.msPerStep = ms / s.steps;
  result.substepsPerStep = static_cast<double>(substeps) / s.steps;

  const double angle = s.omega * s.h * s.steps;
  const Eigen::Rotation2Dd back(-angle);
  Vector exact(n);
  for (int i = 0; i < n; ++i) {
    const Vector2 x = g.position(i).head<2>();
    exact[i] = bump(back * (x - s.center) + s.center, s.blobCenter, s.blobRadius);
  }
  result.health = fieldHealth(state.solvent, max0);
  result.shapeError = liquid_testing::relativeL2(g.areas(), state.solvent, exact);
  result.massError = std::abs(liquid_testing::totalMass(g.areas(), state.solvent) - mass0) / mass0;
  return result;
}

struct RotatingDiscSetup {
  int rings = 48;
  double radius = 1.0;        ///< m
  double omega = 2.0;         ///< rad/s about +z
  double h = 0.01;            ///< s
  double duration = 1.5707963267948966;  ///< s (half a turn at 2 rad/s)
  bool coriolis = true;
  stain::CoriolisScheme scheme = stain::CoriolisScheme::ExactRotation;
  stain::Vector3 blobCenter{0.5, 0, 0};
  double blobRadius = 0.12;
  stain::Vector3 inertialVelocity{0, 0, 0};  ///< v0 (m/s), world
  /// Also a thin film (a tenth of the blob's mass) over the whole disc, so every
  /// vertex is wet and carries the liquid's velocity. Without it the dry
  /// vertices keep the initial relative velocity as a placeholder that no force
  /// updates, and the blob's backtracks read it (at ωh = 2 they land far outside
  /// the blob): an error of the placeholder, not of the Coriolis integration.
  bool filmEverywhere = false;
};

struct RotatingDiscResult {
  bool ok = true;
  std::string failure;       ///< stage and message of the first failed step
  int stepsDone = 0;
  double finalError = 0;     ///< |centroid − (x0 + v0 t)| / R at the end
  double maxError = 0;       ///< the same, largest over the run
  /// Σ ½ A σ |u|² over the same with the exact relative velocity, at the end
  /// (1 at the start; disc frame). Mass smeared by upwind diffusion does not move it.
  double energyRatio = 1;
  double massError = 0;      ///< solvent budget error
  double minOverMax = 0;     ///< min σ_f / max σ_f at the end
  double msPerStep = 0;
  int vertices = 0;
};

inline RotatingDiscResult runRotatingDisc(const RotatingDiscSetup& s) {
  using namespace stain;
  const TriangleMesh mesh = discMesh(s.rings, s.radius);
  const SurfaceTopology topology(mesh.faces, static_cast<int>(mesh.vertexPositions.rows()));
  StainSolverDef def;
  def.switches.densityDiffusion = false;
  def.switches.velocityDiffusion = false;
  def.switches.absorption = def.switches.adsorption = def.switches.evaporation = false;
  def.switches.coriolis = s.coriolis;
  def.switches.coriolisScheme = s.scheme;
  def.gravity = Vector3(0, 0, -9.8);  // normal to the disc: no tangential part
  StainSolver solver(topology, mesh.vertexPositions,
                     isotropicFabricField(static_cast<int>(mesh.faces.rows()), 1e-4, 1e-4), def);
  const int n = static_cast<int>(mesh.vertexPositions.rows());
  const Vector3 w(0, 0, s.omega);
  RowVectors3 velocities(n, 3);
  for (int i = 0; i < n; ++i) velocities.row(i) = w.cross(Vector3(mesh.vertexPositions.row(i))).transpose();
  solver.setInitialMotion(mesh.vertexPositions, velocities);
  DropDef drop;
  drop.centerPoint = s.blobCenter;
  drop.radius = s.blobRadius;
  drop.solventMass = 0.01;
  drop.soluteMass = 0.0;
  solver.addDrop(drop);
  if (s.filmEverywhere) {
    DropDef film;
    film.centerPoint = Vector3::Zero();
    film.radius = 3 * s.radius;
    film.solventMass = 0.1 * drop.solventMass;
    film.soluteMass = 0.0;
    solver.addDrop(film);
  }
  StainState& state = solver.mutableState();
  for (int i = 0; i < n; ++i) {
    const Vector3 rel = s.inertialVelocity - w.cross(Vector3(mesh.vertexPositions.row(i)));
    const Matrix3& F = solver.geometry().extrinsic().frames[static_cast<size_t>(i)];
    state.velocities[i] = Complex(F.col(0).dot(rel), F.col(1).dot(rel));
  }
  const auto centroid = [&](const RowVectors3& positions) {
    const Vector m = solver.state().solvent.cwiseProduct(solver.geometry().intrinsic().vertexDualAreas);
    return Vector3((positions.transpose() * m) / m.sum());
  };
  // Kinetic energy Σ ½ m |u|² over that of the exact relative velocity
  // R(t)ᵀ v0 − ω × x̄ for the same masses: 1 for the exact flow wherever the
  // (numerically smeared) mass has gone, so only velocity errors move it.
  const auto energyRatio = [&](double t) {
    const StainState& st = solver.state();
    const Vector& a = solver.geometry().intrinsic().vertexDualAreas;
    const Vector3 v0 = Eigen::AngleAxisd(-s.omega * t, Vector3::UnitZ()) * s.inertialVelocity;
    double numerical = 0, exact = 0;
    for (int i = 0; i < n; ++i) {
      const double m = a[i] * st.solvent[i];
      numerical += 0.5 * m * std::norm(st.velocities[i]);
      exact += 0.5 * m * (v0 - w.cross(Vector3(mesh.vertexPositions.row(i)))).squaredNorm();
    }
    return numerical / exact;
  };
  const Vector3 start = centroid(mesh.vertexPositions);
  const double energy0 = energyRatio(0);
  const int steps = std::max(1, static_cast<int>(std::lround(s.duration / s.h)));

  RotatingDiscResult result;
  result.vertices = n;
  double ms = 0;
  for (int k = 1; k <= steps; ++k) {
    const Matrix3 R = Eigen::AngleAxisd(s.omega * k * s.h, Vector3::UnitZ()).toRotationMatrix();
    const RowVectors3 positions = mesh.vertexPositions * R.transpose();
    const Stopwatch clock;
    const StepReport report = solver.stepRigid(s.h, positions, R);
    ms += clock.milliseconds();
    if (report.status != StepStatus::Ok) {
      result.ok = false;
      result.failure = std::string(report.stageName()) + ": " + report.message;
      break;
    }
    result.stepsDone = k;
    const Vector3 expected = start + s.inertialVelocity * (k * s.h);
    const double error = (centroid(solver.geometry().extrinsic().nextPositions) - expected).norm() / s.radius;
    result.finalError = error;
    result.maxError = std::max(result.maxError, std::isfinite(error) ? error : 1e300);
  }
  result.msPerStep = ms / std::max(1, result.stepsDone + (result.ok ? 0 : 1));
  result.energyRatio = energyRatio(result.stepsDone * s.h) / energy0;
  result.massError = solver.massBudget().solventError();
  const Vector& sigma = solver.state().solvent;
  result.minOverMax = std::min(0.0, sigma.minCoeff() / sigma.maxCoeff());
  return result;
}

}  // namespace blot::test
