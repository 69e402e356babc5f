// The Coriolis term as a discrete frame change (external_forces.h,
// applyHalfFrameRotation and applyFrameVelocityChange; docs/transport.md): on
// a disc turning rigidly at ω, the liquid's world velocity V = v^{t+½} +
// F^{t+½} u (v^{t+½} the frame velocity of the step, u kept in the step's
// midpoint frame) must be carried unchanged at any ωh, so liquid at rest in
// the inertial frame stays at rest and no kinetic energy is created, and the
// relative velocity must still converge to the continuous one as h → 0.
#include <blot/stain/geometry/mesh_primitives.h>
#include <blot/stain/stain_solver.h>
#include <blot/stain/stages/velocity_advection.h>

#include <gtest/gtest.h>

#include "stain_fixture.h"

#include <algorithm>
#include <cmath>
#include <cstdio>

#include "stain_stage_test_support.h"

namespace blot::stain {
namespace {

constexpr double kPi = 3.14159265358979323846;

struct DiscRun {
  double worldVelocityError = 0;  ///< max over vertices |V_i − v0| / (ω R) at the end (all wet)
  double energyRatio = 0;         ///< Σ m|u|² / Σ m|v0 − ω×x|² in the disc frame at the end
  double relativeError = 0;       ///< max |u_i − F_iᵀ(v0 − ω×x_i)| / (ω R) at the end
  int dryVertices = 0;            ///< vertices that were not wet at the end (should be 0)
};

/// A film covering the whole disc (radius 1 m, every vertex wet, so no vertex
/// keeps a stale velocity), moving at v0 in the inertial frame while the disc
/// turns at ω about z; diffusion and interaction off. `scheme` as given. The
/// disc is a window on an unbounded film (a moving film crosses its rim), so
/// the rim is no wall (PhysicsSwitches::boundaryWall off; with the wall, the
/// film at rest still passes: its flow is along the rim).
DiscRun runDisc(double omega, double h, int steps, const Vector3& v0,
                CoriolisScheme scheme = CoriolisScheme::ExactRotation, int rings = 12) {
  const double radius = 1.0;
  const TriangleMesh mesh = discMesh(rings, radius);
  const SurfaceTopology topology(mesh.faces, static_cast<int>(mesh.vertexPositions.rows()));
  StainSolverDef def;
  def.switches.densityDiffusion = false;
  def.switches.velocityDiffusion = false;
  def.switches.absorption = def.switches.adsorption = def.switches.evaporation = false;
  def.switches.coriolisScheme = scheme;
  def.switches.boundaryWall = v0.squaredNorm() == 0.0;
  def.gravity = Vector3(0, 0, -9.8);  // normal to the disc: no tangential part
  StainSolver solver(topology, mesh.vertexPositions,
                     isotropicFabricField(static_cast<int>(mesh.faces.rows()), 1e-4, 1e-4), def);
  const int n = static_cast<int>(mesh.vertexPositions.rows());
  const Vector3 w(0, 0, omega);
  solver.setInitialMotion(mesh.vertexPositions, testing::spinVelocities(mesh.vertexPositions, w));
  DropDef drop;
  drop.centerPoint = Vector3(0, 0, 0);
  drop.radius = 3 * radius;  // covers the disc
  drop.solventMass = 0.01;
  drop.soluteMass = 0.0;
  solver.addDrop(drop);
  StainState& state = solver.mutableState();
  for (int i = 0; i < n; ++i) {
    const Vector3 rel = v0 - w.cross(Vector3(mesh.vertexPositions.row(i)));
    const Matrix3& F = solver.geometry().extrinsic().frames[static_cast<size_t>(i)];
    state.velocities[i] = Complex(F.col(0).dot(rel), F.col(1).dot(rel));
  }
  for (int k = 1; k <= steps; ++k) {
    const Matrix3 R = Eigen::AngleAxisd(omega * k * h, Vector3::UnitZ()).toRotationMatrix();
    const StepReport report = solver.stepRigid(h, mesh.vertexPositions * R.transpose(), R);
    EXPECT_EQ(report.status, StepStatus::Ok) << report.stageName() << ": " << report.message;
    if (report.status != StepStatus::Ok) return {};
  }
  // After step(h, p(t+h)) the stain is at t + h; u is in the step's midpoint
  // frames, F^{t+h} turned back by half the frame increment about z, the
  // increment being the shortest rotation (ωh wrapped into [−π, π]: a frame
  // sampled once per step cannot tell ωh = 5 from 5 − 2π).
  const ExtrinsicGeometry& ex = solver.geometry().extrinsic();
  const Vector& area = solver.geometry().intrinsic().vertexDualAreas;
  const StainState& s = solver.state();
  DiscRun run;
  double numerical = 0, exact = 0;
  for (int i = 0; i < n; ++i) {
    if (!(s.solvent[i] > def.liquid.wetThreshold)) ++run.dryVertices;
    const Matrix3& F = ex.nextFrames[static_cast<size_t>(i)];
    const Matrix3 midpoint = Eigen::AngleAxisd(-0.5 * std::remainder(omega * h, 2 * kPi), Vector3::UnitZ()) * F;
    const Complex u = s.velocities[i];
    const Vector3 frameVelocity = (ex.nextPositions.row(i) - ex.positions.row(i)).transpose() / h;
    const Vector3 world = frameVelocity + u.real() * midpoint.col(0) + u.imag() * midpoint.col(1);
    run.worldVelocityError = std::max(run.worldVelocityError, (world - v0).norm() / (omega * radius));
    const Vector3 rel = v0 - w.cross(Vector3(ex.nextPositions.row(i)));
    const Complex exactU(F.col(0).dot(rel), F.col(1).dot(rel));
    run.relativeError = std::max(run.relativeError, std::abs(u - exactU) / (omega * radius));
    const double m = area[i] * s.solvent[i];
    numerical += m * std::norm(u);
    exact += m * rel.squaredNorm();
  }
  run.energyRatio = numerical / exact;
  return run;
}

double sinc(double x) { return x == 0 ? 1.0 : std::sin(x) / x; }

// Liquid at rest in the inertial frame on a disc turning at ωh = 2 and 5 rad
// per step: its world velocity stays zero to rounding, and its relative speed
// is the frame's chord speed ω r sinc(ωh/2) (≤ the exact ω r: no energy gain).
TEST(CoriolisFrame, LiquidAtRestStaysAtRestAtLargeOmegaH) {
  struct Case {
    double omega, h;
  };
  for (const Case c : {Case{2.0, 1.0}, Case{50.0, 0.1}, Case{2.0, 0.01}}) {
    const DiscRun r = runDisc(c.omega, c.h, 50, Vector3::Zero());
    const double chord = sinc(0.5 * c.omega * c.h);
    std::printf("at rest, omega %g h %g: |V|/(omega R) %.2e, energy ratio %.6f (sinc^2 %.6f), dry %d\n", c.omega,
                c.h, r.worldVelocityError, r.energyRatio, chord * chord, r.dryVertices);
    EXPECT_EQ(r.dryVertices, 0);
    EXPECT_LT(r.worldVelocityError, 1e-10);
    EXPECT_NEAR(r.energyRatio, chord * chord, 1e-9);
    EXPECT_LE(r.energyRatio, 1.0 + 1e-12);
  }
}

// A film sliding at v0 in the inertial frame keeps v0 at every vertex, at any
// ωh: the frame change and the frame velocity along the backtrack cancel the
// rotation exactly for a uniform world velocity.
TEST(CoriolisFrame, InertialVelocityIsCarriedUnchanged) {
  const Vector3 v0(0.3, -0.1, 0.0);
  for (const double h : {1.0, 0.1, 0.01}) {
    const DiscRun r = runDisc(2.0, h, 30, v0);
    std::printf("sliding at v0, omega 2 h %g: |V - v0|/(omega R) %.2e\n", h, r.worldVelocityError);
    EXPECT_LT(r.worldVelocityError, 1e-10);
  }
}

// The previous split step (exp(−2iω_n h) after advection) fails at ωh = 2;
// the discrete frame change does not. This is the regression the stability
// sweep found (docs/accuracy.md). Without the liquid band the split
// step gained energy (×4.8: dry vertices the film left kept their stale u
// and fed it back); with the velocity extended from the liquid it instead
// gathers the film into a few vertices at the centre, and its world velocity
// is far from the inertial rest either way.
TEST(CoriolisFrame, SplitRotationFailsWhereTheFrameChangeDoesNot) {
  const DiscRun split = runDisc(2.0, 1.0, 20, Vector3::Zero(), CoriolisScheme::SplitRotation);
  const DiscRun ours = runDisc(2.0, 1.0, 20, Vector3::Zero(), CoriolisScheme::ExactRotation);
  std::printf("omega h = 2, 20 steps: energy ratio split %.3f, ours %.3f; dry vertices split %d, ours %d; "
              "|V|/(omega R) split %.3g, ours %.3g\n",
              split.energyRatio, ours.energyRatio, split.dryVertices, ours.dryVertices, split.worldVelocityError,
              ours.worldVelocityError);
  EXPECT_GT(split.dryVertices, 400) << "the split step gathers the film (469 vertices) at the centre";
  EXPECT_GT(split.worldVelocityError, 0.1);
  EXPECT_EQ(ours.dryVertices, 0);
  EXPECT_LT(ours.worldVelocityError, 1e-10);
  EXPECT_LE(ours.energyRatio, 1.0 + 1e-12);
}

// Relative velocity against the continuous one, F^{t+h}ᵀ(v0 − ω × x), at
// T = 0.4 s for h halved twice: first order. u is kept in the midpoint frame
// F^{t+h/2}, so read in F^{t+h} the inertial part v0 is turned by ωh/2: an
// error of (ωh/2)|v0| = h|v0|/(2R) in units of ωR (ω = 2 rad/s, R = 1 m).
TEST(CoriolisFrame, RelativeVelocityConvergesAtFirstOrder) {
  const Vector3 v0(0.3, 0.0, 0.0);
  const double T = 0.4;
  double previous = 0;
  for (const double h : {0.02, 0.01, 0.005}) {
    const DiscRun r = runDisc(2.0, h, static_cast<int>(std::lround(T / h)), v0);
    std::printf("h %g: max relative velocity error %.3e (omega R)\n", h, r.relativeError);
    EXPECT_LT(r.relativeError, h * v0.norm());  // twice the expected h|v0|/(2R)
    if (previous > 0) {
      EXPECT_GT(std::log2(previous / r.relativeError), 0.9);
    }
    previous = r.relativeError;
  }
}

// The foot stencil advectVelocity records (what the frame velocity is
// interpolated with) is the foot point of the backtrack: on a flat grid with a
// uniform world velocity U, Σ_c w_c p_{k_c} = p_i − hU wherever the ray stays
// inside the mesh, within the one-ring and after a strip walk of several
// triangles, and the weights are convex.
TEST(CoriolisFrame, FootStencilIsTheBacktrackFootPoint) {
  const testing::StageGeometry g(gridMesh(12, 10, 1.2, 1.0));  // spacing 0.1 m
  const Vector3 U(0.37, -0.21, 0.0);
  int interior = 0;
  for (const double h : {0.05, 0.6}) {  // foot 0.02 m (in the ring) and 0.26 m away (strip walk)
    StainState state = testing::zeroState(g.vertexCount());
    for (int i = 0; i < g.vertexCount(); ++i) state.velocities(i) = g.toFrame(i, U);
    PhysicsSwitches switches;
    const StepContext ctx = makeStepContext(h, Vector3::Zero(), switches, LiquidParameters{});
    VelocityAdvectionScratch scratch;
    advectVelocity(ctx, g.topology(), g.intrinsic, {}, scratch, state);
    for (int i = 0; i < g.vertexCount(); ++i) {
      const Vector3 foot = g.position(i) - h * U;
      if (foot.x() < 1e-9 || foot.x() > 1.2 - 1e-9 || foot.y() < 1e-9 || foot.y() > 1.0 - 1e-9) continue;
      ++interior;
      Vector3 stencil = Vector3::Zero();
      double sum = 0;
      for (int c = 0; c < 3; ++c) {
        const double w = scratch.footWeights(i, c);
        EXPECT_GE(w, 0.0);
        sum += w;
        stencil += w * g.position(scratch.footVertices(i, c));
      }
      EXPECT_NEAR(sum, 1.0, 1e-12) << "vertex " << i;
      EXPECT_LT((stencil - foot).norm(), 1e-12) << "vertex " << i << ", h " << h;
    }
  }
  EXPECT_GT(interior, 100);
}

}  // namespace
}  // namespace blot::stain
