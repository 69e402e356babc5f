#pragma once
// The stain fixture every stage test, study and stage benchmark builds on:
// both geometry tiers of a static mesh as the solver builds them on the rest
// shape (positions at t − h = t = t + h), a zero state, fabrics, mass sums,
// and the exact anisotropic Gaussian. The geometry-heavy stage tests wrap the
// same tiers in StageGeometry (tests/stain/stain_stage_test_support.h).
#include <blot/stain/stages/diffusion.h>
#include <blot/stain/geometry/extrinsic_geometry.h>
#include <blot/stain/geometry/intrinsic_geometry.h>
#include <blot/stain/geometry/mesh_primitives.h>
#include <blot/stain/geometry/operators.h>
#include <blot/stain/stain_state.h>
#include <blot/stain/geometry/surface_geometry.h>
#include <blot/stain/geometry/surface_topology.h>
#include <blot/stain/geometry/transport.h>

#include <cmath>
#include <stdexcept>
#include <utility>

namespace blot::stain::testing {

/// Both geometry tiers of a static mesh, exactly as SurfaceGeometry builds
/// them on the rest shape.
struct StaticTiers {
  IntrinsicGeometry intrinsic;
  ExtrinsicGeometry extrinsic;
};
inline StaticTiers staticTiers(const SurfaceTopology& topology, const RowVectors3& positions,
                               const FabricField& fabric) {
  const SurfaceGeometry geometry(topology, positions, fabric);
  return {geometry.intrinsic(), geometry.extrinsic()};
}

/// All fields zero, for `n` vertices (without StainState::resize, so these
/// tests do not depend on where that is implemented).
inline StainState zeroState(int n) {
  StainState s;
  s.velocities = ComplexVector::Zero(n);
  s.solvent = Vector::Zero(n);
  s.solute = Vector::Zero(n);
  s.absorbedSolvent = Vector::Zero(n);
  s.absorbedSolute = Vector::Zero(n);
  s.adsorbedSolute = Vector::Zero(n);
  return s;
}

/// w × x for every row x of `positions` (m/s): the surface velocities of a
/// rigid spin about the origin, for StainSolver::setInitialMotion.
inline RowVectors3 spinVelocities(const RowVectors3& positions, const Vector3& w) {
  RowVectors3 velocities(positions.rows(), 3);
  for (Eigen::Index i = 0; i < positions.rows(); ++i)
    velocities.row(i) = w.cross(Vector3(positions.row(i).transpose())).transpose();
  return velocities;
}

}  // namespace blot::stain::testing

namespace blot::stain::liquid_testing {

using testing::zeroState;

constexpr double kPi = 3.14159265358979323846;

/// Row (s_ww, s_wp, s_pp) of a tensor with eigenvalues `weft` and `warp`
/// along the fabric's own axes (the weft direction carries the orientation).
inline Eigen::RowVector3d fabricTensor(double weft, double warp) { return {weft, 0.0, warp}; }

/// The same tensors on every face, with the weft at `weftAngle` (rad) from the
/// x axis in the z = 0 plane.
inline FabricField uniformFabric(int faceCount, const Eigen::RowVector3d& densityTensor,
                                 const Eigen::RowVector3d& velocityTensor, double weftAngle) {
  FabricField fabric;
  fabric.densityTensors = densityTensor.replicate(faceCount, 1);
  fabric.velocityTensors = velocityTensor.replicate(faceCount, 1);
  fabric.weftDirections =
      Eigen::RowVector3d(std::cos(weftAngle), std::sin(weftAngle), 0.0).replicate(faceCount, 1);
  return fabric;
}

/// Isotropic unit tensors for both fields.
inline FabricField isotropicFabric(int faceCount) {
  return uniformFabric(faceCount, fabricTensor(1, 1), fabricTensor(1, 1), 0.0);
}

/// Both geometry tiers of one static mesh, as SurfaceGeometry builds them.
struct LiquidMesh {
  TriangleMesh mesh;
  SurfaceTopology topology;
  IntrinsicGeometry intrinsic;
  ExtrinsicGeometry extrinsic;

  LiquidMesh(TriangleMesh m, const FabricField& fabric)
      : mesh(std::move(m)),
        topology(mesh.faces, static_cast<int>(mesh.vertexPositions.rows()), "liquid test mesh") {
    testing::StaticTiers tiers = testing::staticTiers(topology, mesh.vertexPositions, fabric);
    intrinsic = std::move(tiers.intrinsic);
    extrinsic = std::move(tiers.extrinsic);
  }
  int vertexCount() const { return topology.vertexCount(); }
  int faceCount() const { return topology.faceCount(); }
  const Vector& areas() const { return intrinsic.vertexDualAreas; }
  Vector3 position(int i) const { return mesh.vertexPositions.row(i).transpose(); }
};

/// Σ A_i σ_i (kg), summed in index order.
inline double totalMass(const Vector& areas, const Vector& densities) {
  double sum = 0.0;
  for (Eigen::Index i = 0; i < areas.size(); ++i) sum += areas[i] * densities[i];
  return sum;
}

/// 2x2 tensor with eigenvalues (weft, warp), weft direction at `angle` from x.
inline Matrix2 rotatedTensor(double weft, double warp, double angle) {
  const double c = std::cos(angle), s = std::sin(angle);
  Matrix2 rotation;
  rotation << c, -s, s, c;
  return rotation * Eigen::Vector2d(weft, warp).asDiagonal() * rotation.transpose();
}

/// Unit-mass Gaussian density of the given covariance (m²) at x: the exact
/// solution of ∂σ/∂t = ∇·(D∇σ) in the plane from covariance Σ0 is this with
/// covariance Σ0 + 2 D t.
inline double gaussianDensity(const Vector2& x, const Vector2& center, const Matrix2& covariance) {
  const Vector2 d = x - center;
  return std::exp(-0.5 * d.dot(covariance.inverse() * d)) / (2.0 * kPi * std::sqrt(covariance.determinant()));
}

/// The convergence problem of diffusion_test and the convergence study: a
/// unit-mass Gaussian of standard deviation `spread` centred in [0,1]², a
/// constant tensor with eigenvalues (1, 0.1) m²/s and weft at 30°, run to
/// T = spread²/4 (the far boundary stays > 6.8 standard deviations away, so the
/// no-flux boundary changes the solution by < 1e-10 of its peak).
struct GaussianProblem {
  double spread = 0.06;
  double weft = 1.0, warp = 0.1, weftAngle = kPi / 6;
  Vector2 center{0.5, 0.5};
  double endTime() const { return spread * spread / 4; }
  Matrix2 tensor() const { return rotatedTensor(weft, warp, weftAngle); }
  FabricField fabric(int faceCount) const {
    return uniformFabric(faceCount, fabricTensor(weft, warp), fabricTensor(1, 1), weftAngle);
  }
  /// Exact density at the vertices at time t.
  Vector exact(const LiquidMesh& g, double t) const {
    const Matrix2 covariance = spread * spread * Matrix2::Identity() + 2 * t * tensor();
    Vector s(g.vertexCount());
    for (int i = 0; i < g.vertexCount(); ++i)
      s[i] = gaussianDensity(g.position(i).head<2>(), center, covariance);
    return s;
  }
};

/// K steps of size T/K through `diffuse` (densities only, no limiter: this
/// measures the discretization), either backward Euler or Crank–Nicolson built
/// from it (σ ← 2 BE_{Δt/2}(σ) − σ, which is exactly CN for a linear system).
inline Vector integrateDiffusion(const LiquidMesh& g, const Vector& initial, double endTime, int steps,
                                 bool crankNicolson) {
  const double h = crankNicolson ? endTime / steps / 2 : endTime / steps;
  DiffusionSystems systems;
  systems.setSolverChoice(DiffusionSolverChoice::Direct);  // backward Euler, not Auto's RKL2
  if (systems.factorize(g.intrinsic, h) != SolverStatus::Ok) throw std::runtime_error("factorize failed");
  DiffusionScratch scratch;
  scratch.resize(g.vertexCount());
  StainState state = zeroState(g.vertexCount());
  state.solvent = initial;
  PhysicsSwitches switches;
  switches.velocityDiffusion = false;
  switches.positivityLimiter = false;
  const StepContext ctx = makeStepContext(h, Vector3(0, 0, -9.8), switches, LiquidParameters{});
  Vector before;
  for (int k = 0; k < steps; ++k) {
    before = state.solvent;
    if (diffuse(ctx, g.intrinsic, systems, scratch, state).status != SolverStatus::Ok) {
      throw std::runtime_error("diffuse failed");
    }
    if (crankNicolson) state.solvent = 2 * state.solvent - before;
  }
  return state.solvent;
}

/// The semi-discrete solution at T with a time error far below any spatial
/// error: Crank–Nicolson with K and 2K steps, Richardson-extrapolated (O(Δt⁴)).
inline Vector semiDiscreteReference(const LiquidMesh& g, const Vector& initial, double endTime, int steps) {
  const Vector coarse = integrateDiffusion(g, initial, endTime, steps, true);
  const Vector fine = integrateDiffusion(g, initial, endTime, 2 * steps, true);
  return (4 * fine - coarse) / 3;
}

/// Smooth compact spot (1 − r²/R²)² of peak `peak` at `center` (z = 0 plane).
inline Vector spot(const LiquidMesh& g, const Vector2& center, double radius, double peak) {
  Vector s = Vector::Zero(g.vertexCount());
  for (int i = 0; i < g.vertexCount(); ++i) {
    const double r = (g.position(i).head<2>() - center).norm() / radius;
    if (r < 1) s[i] = peak * (1 - r * r) * (1 - r * r);
  }
  return s;
}

/// Relative mass-weighted L2 error sqrt(Σ A (a − b)²) / sqrt(Σ A b²).
inline double relativeL2(const Vector& areas, const Vector& a, const Vector& reference) {
  return std::sqrt((areas.array() * (a - reference).array().square()).sum() /
                   (areas.array() * reference.array().square()).sum());
}

}  // namespace blot::stain::liquid_testing
