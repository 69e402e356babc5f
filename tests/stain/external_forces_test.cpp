// applyExternalForces: linear inertia on a uniformly accelerated sheet,
// tangential gravity on a tilted plane, Coriolis exact rotation against the
// explicit update's closed-form energy gain, the wet mask and the switches;
// the boundary wall against the mesh's world geometry.
#include <blot/stain/stages/external_forces.h>
#include <blot/stain/stages/liquid_band.h>
#include <blot/stain/geometry/operators.h>
#include <blot/stain/geometry/surface_geometry.h>
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdio>

#include "stain_stage_test_support.h"

namespace blot::stain {
namespace {

using testing::StageGeometry;
using testing::zeroState;

// A 6x4 grid rotated out of the z = 0 plane: a flat sheet with a generic normal.
StageGeometry tiltedSheet(double tiltAngle) {
  TriangleMesh mesh = gridMesh(6, 4, 1.2, 0.8);
  const Matrix3 rotation =
      (Eigen::AngleAxisd(tiltAngle, Vector3::UnitX()) * Eigen::AngleAxisd(0.3, Vector3::UnitZ()))
          .toRotationMatrix();
  mesh.vertexPositions = (mesh.vertexPositions * rotation.transpose()).eval();
  return StageGeometry(mesh);
}

StepContext contextOnly(double h, bool gravity, bool inertia, bool coriolis) {
  PhysicsSwitches switches;
  switches.gravity = gravity;
  switches.linearInertia = inertia;
  switches.coriolis = coriolis;
  return makeStepContext(h, Vector3(0, 0, -9.8), switches, LiquidParameters{});
}

// Sheet under uniform acceleration a (p̈ = a at every vertex), forces alone:
// the liquid's velocity relative to the sheet is −a_tangential · t.
TEST(ExternalForces, UniformAccelerationGivesMinusTangentialAccelerationTimesTime) {
  StageGeometry g = tiltedSheet(0.7);
  const Vector3 a(1.5, -2.0, 3.25);
  for (int i = 0; i < g.vertexCount(); ++i) g.extrinsic.vertexAccelerations.row(i) = a.transpose();
  const StepContext ctx = contextOnly(0.01, false, true, true);
  StainState state = zeroState(g.vertexCount());
  const int steps = 250;
  for (int s = 0; s < steps; ++s) applyExternalForces(ctx, g.extrinsic, {}, state);
  const double t = steps * ctx.h;
  const Vector3 normal = g.extrinsic.vertexNormals.row(0).transpose();
  const Vector3 expected = -t * (a - a.dot(normal) * normal);
  for (int i = 0; i < g.vertexCount(); ++i) {
    EXPECT_LT((g.toWorld(i, state.velocities(i)) - expected).norm(), 1e-10) << "vertex " << i;
  }
}

// The same through the real geometry cache: a tilted sheet moving as
// p(t) = p̄ + v t + ½ a t² (centred differences of a quadratic are exact, so
// SurfaceGeometry's p̈ is a to rounding), gravity on: after n steps the
// velocity relative to the sheet is t (g − a) projected on the sheet.
TEST(ExternalForces, UniformAccelerationThroughSurfaceGeometry) {
  const StageGeometry sheet = tiltedSheet(0.6);
  const SurfaceTopology& topology = sheet.topology();
  const RowVectors3 rest = sheet.geometry.mesh.vertexPositions;
  const int n = topology.vertexCount();
  FabricField fabric;
  fabric.densityTensors = identityFaceTensors(topology.faceCount());
  fabric.velocityTensors = identityFaceTensors(topology.faceCount());
  fabric.weftDirections = RowVectors3::Zero(topology.faceCount(), 3);
  const Eigen::RowVector3d velocity(0.4, -0.1, 0.2), acceleration(2.0, 1.0, -3.0);
  auto positionsAt = [&](double t) -> RowVectors3 {
    return rest.rowwise() + (t * velocity + 0.5 * t * t * acceleration);
  };
  const double h = 0.01;
  SurfaceGeometry geometry(topology, rest, fabric);
  geometry.setPreviousPositions(positionsAt(-h));
  const StepContext ctx = contextOnly(h, true, true, true);
  StainState state = zeroState(n);
  const int steps = 200;
  for (int s = 0; s < steps; ++s) {
    geometry.refreshExtrinsic(positionsAt((s + 1) * h), h);
    applyExternalForces(ctx, geometry.extrinsic(), {}, state);
  }
  const double t = steps * h;
  const Vector3 normal = sheet.extrinsic.vertexNormals.row(0).transpose();
  const Vector3 force = ctx.gravity - acceleration.transpose();
  const Vector3 expected = t * (force - force.dot(normal) * normal);
  double worst = 0.0;
  for (int i = 0; i < n; ++i) {
    const Matrix3& frame = geometry.extrinsic().frames[static_cast<size_t>(i)];
    const Vector3 world =
        frame.col(0) * state.velocities(i).real() + frame.col(1) * state.velocities(i).imag();
    worst = std::max(worst, (world - expected).norm());
  }
  std::printf("accelerated sheet via SurfaceGeometry: |u| = %.6f, max error %.2e\n", expected.norm(), worst);
  EXPECT_LT(worst, 1e-10);
}

// Plane tilted by φ: gravity's tangential part has magnitude g sin φ.
TEST(ExternalForces, TangentialGravityOnTiltedPlaneIsGSinPhiTimesTime) {
  for (const double phi : {0.0, 0.3, 1.1, 1.5707963267948966}) {
    StageGeometry g = tiltedSheet(phi);
    const StepContext ctx = contextOnly(0.02, true, false, false);
    StainState state = zeroState(g.vertexCount());
    const int steps = 100;
    for (int s = 0; s < steps; ++s) applyExternalForces(ctx, g.extrinsic, {}, state);
    const double t = steps * ctx.h;
    const Vector3 normal = g.extrinsic.vertexNormals.row(0).transpose();
    const Vector3 downhill = ctx.gravity - ctx.gravity.dot(normal) * normal;
    for (int i = 0; i < g.vertexCount(); ++i) {
      const Vector3 world = g.toWorld(i, state.velocities(i));
      EXPECT_NEAR(std::abs(state.velocities(i)), 9.8 * std::sin(phi) * t, 1e-10) << "phi " << phi;
      EXPECT_LT((world - t * downhill).norm(), 1e-10) << "phi " << phi << " vertex " << i;
    }
  }
}

// Exact rotation keeps |u| over 10^4 steps; explicit multiplies it by
// (1 + 4ω²h²)^{n/2}; both turn u clockwise for ω_n > 0 (−2ω × u).
// Tolerance for the exact scheme: each complex product rounds by up to ~1 ulp
// and the rounding of a fixed rotation is biased, so n steps drift up to
// n·ε ≈ 1.1e-12 relative (measured: 2.2e-13); 1e-14 is below what double
// precision can promise for 10^4 products.
TEST(ExternalForces, CoriolisExactRotationPreservesSpeedExplicitGainsClosedForm) {
  StageGeometry g = tiltedSheet(0.0);
  const double omega = 1.0, h = 0.01;
  for (int i = 0; i < g.vertexCount(); ++i) g.extrinsic.vertexAngularVelocities(i, 2) = omega;
  StepContext exact = contextOnly(h, false, false, true);
  StepContext explicitScheme = exact;
  explicitScheme.switches.coriolisScheme = CoriolisScheme::Explicit;
  const Complex u0(0.3, -0.4);

  StainState a = zeroState(g.vertexCount()), b = zeroState(g.vertexCount());
  a.velocities.setConstant(u0);
  b.velocities.setConstant(u0);
  applyExternalForces(exact, g.extrinsic, {}, a);
  EXPECT_LT(std::abs(a.velocities(0) - u0 * std::polar(1.0, -2.0 * omega * h)), 1e-16);

  const int steps = 10000;
  a.velocities.setConstant(u0);
  for (int s = 0; s < steps; ++s) {
    applyExternalForces(exact, g.extrinsic, {}, a);
    applyExternalForces(explicitScheme, g.extrinsic, {}, b);
  }
  const double growth = std::pow(1.0 + 4.0 * omega * omega * h * h, steps / 2.0);
  for (int i = 0; i < g.vertexCount(); ++i) {
    EXPECT_NEAR(std::abs(a.velocities(i)), std::abs(u0), 1e-12 * std::abs(u0)) << "vertex " << i;
    EXPECT_NEAR(std::abs(b.velocities(i)) / std::abs(u0), growth, 1e-10 * growth) << "vertex " << i;
  }
  // After 10^4 steps the exact scheme has turned u by −2ωt (mod 2π).
  const Complex expected = u0 * std::polar(1.0, -2.0 * omega * h * steps);
  EXPECT_LT(std::abs(a.velocities(0) - expected), 1e-11);
  EXPECT_GT(growth, 7.0);  // e² ≈ 7.39: the explicit scheme is clearly unstable
}

TEST(ExternalForces, DryVerticesAndSwitchedOffTermsAreUntouched) {
  StageGeometry g = tiltedSheet(0.8);
  for (int i = 0; i < g.vertexCount(); ++i) {
    g.extrinsic.vertexAccelerations.row(i) << 1.0, 2.0, 3.0;
    g.extrinsic.vertexAngularVelocities(i, 2) = 0.5;
  }
  std::vector<char> wet(static_cast<size_t>(g.vertexCount()), 0);
  for (size_t i = 0; i < wet.size(); i += 3) wet[i] = 1;
  StainState state = zeroState(g.vertexCount());
  state.velocities.setConstant(Complex(0.1, 0.2));
  applyExternalForces(contextOnly(0.01, true, true, true), g.extrinsic, wet, state);
  for (int i = 0; i < g.vertexCount(); ++i) {
    if (wet[static_cast<size_t>(i)]) {
      EXPECT_GT(std::abs(state.velocities(i) - Complex(0.1, 0.2)), 1e-3);
    } else {
      EXPECT_EQ(state.velocities(i), Complex(0.1, 0.2));
    }
  }
  StainState off = zeroState(g.vertexCount());
  off.velocities.setConstant(Complex(0.1, 0.2));
  applyExternalForces(contextOnly(0.01, false, false, false), g.extrinsic, {}, off);
  for (int i = 0; i < g.vertexCount(); ++i) EXPECT_EQ(off.velocities(i), Complex(0.1, 0.2));
}

// Fibre-held liquid carries no velocity: a wet-set vertex with no free liquid
// (absorbed only) has u cleared before the forces, so it gains h·g per step
// instead of accumulating it; one with free liquid, and every vertex outside
// the wet set (the band's extension, kept), are untouched; the switch off
// keeps the old accumulation.
TEST(ExternalForces, WetVerticesWithoutFreeLiquidCarryNoVelocity) {
  StageGeometry g = tiltedSheet(0.8);
  const int n = g.vertexCount();
  std::vector<char> band(static_cast<size_t>(n), 1);
  StainState state = zeroState(n);
  state.velocities.setConstant(Complex(3.0, -4.0));
  for (int i = 0; i < n; i += 2) {
    band[static_cast<size_t>(i)] = LiquidBand::kHoldsLiquid;
    state.absorbedSolvent(i) = 0.5;
    if (i % 4 == 0) state.solvent(i) = 0.2;  // free liquid too
  }
  StepContext ctx = contextOnly(0.01, false, false, false);
  StainState off = state;
  clearVelocityWithoutFreeLiquid(ctx, band, state);
  for (int i = 0; i < n; ++i) {
    const bool cleared = band[static_cast<size_t>(i)] == LiquidBand::kHoldsLiquid && i % 4 != 0;
    EXPECT_EQ(state.velocities(i), cleared ? Complex(0.0, 0.0) : Complex(3.0, -4.0)) << "vertex " << i;
  }
  ctx.switches.velocityOnFreeLiquid = false;
  clearVelocityWithoutFreeLiquid(ctx, band, off);
  for (int i = 0; i < n; ++i) EXPECT_EQ(off.velocities(i), Complex(3.0, -4.0));
}

// The boundary wall against the world geometry of the mesh, not the polar map
// it is computed from: at every boundary vertex of a tilted 6x4 sheet (generic
// frames; straight edges with fans of π, corners of π/2) and for 24 world
// directions d in the sheet's plane, u = d in the vertex's frame becomes the
// nearest point of the fan spanned by the two boundary edges e1, e2 (d
// itself when d = a e1 + b e2 with a, b ≥ 0, else the larger of the clamped
// projections onto e1 and e2). Interior and unmarked vertices keep u; the
// switch off keeps every u. Tolerance 1e-12: a few roundings of unit vectors.
TEST(ExternalForces, BoundaryWallKeepsTheNearestDirectionThatStaysOnTheMesh) {
  StageGeometry g = tiltedSheet(0.7);
  const int n = g.vertexCount();
  const SurfaceTopology& topology = g.topology();
  const Vector3 normal = g.extrinsic.vertexNormals.row(0).transpose();
  const Vector3 a = (g.position(1) - g.position(0)).normalized();
  const Vector3 b = normal.cross(a);
  std::vector<char> band(static_cast<size_t>(n), 1);
  band[0] = 0;  // a corner outside the band keeps its u
  const StepContext ctx = contextOnly(0.01, true, false, false);
  int boundaryVertices = 0, changedTotal = 0;
  for (int k = 0; k < 24; ++k) {
    const double angle = 2.0 * std::acos(-1.0) * (k + 0.5) / 24.0;
    const Vector3 d = 0.7 * (std::cos(angle) * a + std::sin(angle) * b);
    StainState state = zeroState(n);
    for (int i = 0; i < n; ++i) state.velocities(i) = g.toFrame(i, d);
    StainState off = state;
    changedTotal += applyBoundaryWall(ctx, topology, g.intrinsic, band, state);
    boundaryVertices = 0;
    for (int i = 0; i < n; ++i) {
      const Vector3 got = g.toWorld(i, state.velocities(i));
      if (!topology.vertexIsBoundary()[static_cast<size_t>(i)] || !band[static_cast<size_t>(i)]) {
        EXPECT_EQ(state.velocities(i), off.velocities(i)) << "vertex " << i;
        continue;
      }
      ++boundaryVertices;
      const std::vector<int>& ring = topology.ringNeighbors();
      const int first = ring[static_cast<size_t>(topology.ringOffsets()[static_cast<size_t>(i)])];
      const int last = ring[static_cast<size_t>(topology.ringOffsets()[static_cast<size_t>(i) + 1] - 1)];
      const Vector3 e1 = (g.position(first) - g.position(i)).normalized();
      const Vector3 e2 = (g.position(last) - g.position(i)).normalized();
      // d = α e1 + β e2 in the plane (e1, e2 independent: fans below π here
      // or exactly π, where e2 = −e1 and the test is the side of the edge).
      Vector3 expected;
      if ((e1 + e2).norm() < 1e-9) {
        const Vector3 inward = normal.cross(e1);  // the fan is on e1's left
        expected = d.dot(inward) >= 0.0 ? d : Vector3(d - d.dot(inward) * inward);
      } else {
        Eigen::Matrix2d m;
        m << e1.dot(e1), e1.dot(e2), e1.dot(e2), e2.dot(e2);
        const Eigen::Vector2d c = m.inverse() * Eigen::Vector2d(e1.dot(d), e2.dot(d));
        if (c[0] >= 0.0 && c[1] >= 0.0) {
          expected = d;
        } else {
          const double p1 = std::max(0.0, d.dot(e1)), p2 = std::max(0.0, d.dot(e2));
          expected = p1 >= p2 ? Vector3(p1 * e1) : Vector3(p2 * e2);
        }
      }
      EXPECT_LT((got - expected).norm(), 1e-12) << "vertex " << i << " direction " << k;
    }
    StepContext openCtx = ctx;
    openCtx.switches.boundaryWall = false;
    EXPECT_EQ(applyBoundaryWall(openCtx, topology, g.intrinsic, band, off), 0);
    for (int i = 0; i < n; ++i) EXPECT_EQ(off.velocities(i), g.toFrame(i, d));
  }
  EXPECT_EQ(boundaryVertices, 2 * (6 + 4) - 1);  // the 7x5 grid's rim less vertex 0
  EXPECT_GT(changedTotal, 24 * 4);  // every direction points off the mesh somewhere
}

// A vertical sheet (the hanging flag's hem): gravity pushes the liquid
// against the bottom edge. With the wall, u there stays tangent to the edge
// (zero after many steps, since gravity is normal to it) while interior u
// grows as g t; open, the hem's u grows like the interior's (the unbounded
// velocity that set the Courant number of a soaked flag's hem).
TEST(ExternalForces, BoundaryWallStopsGravityAtTheHem) {
  TriangleMesh mesh = gridMesh(6, 4, 1.2, 0.8);
  mesh.vertexPositions = (mesh.vertexPositions * Eigen::AngleAxisd(std::acos(-1.0) / 2, Vector3::UnitX())
                                                     .toRotationMatrix()
                                                     .transpose())
                             .eval();  // y -> z: the sheet hangs in the x-z plane, its y = 0 edge at the bottom
  StageGeometry g(mesh);
  const int n = g.vertexCount();
  std::vector<char> band(static_cast<size_t>(n), 1);
  StepContext ctx = contextOnly(0.01, true, false, false);
  StainState wall = zeroState(n), open = zeroState(n);
  const int steps = 200;
  for (int s = 0; s < steps; ++s) {
    applyBodyForces(ctx, g.extrinsic, band, wall);
    applyBoundaryWall(ctx, g.topology(), g.intrinsic, band, wall);
    applyBodyForces(ctx, g.extrinsic, band, open);
  }
  const double t = steps * ctx.h;
  for (int i = 0; i < n; ++i) {
    const double height = g.position(i).z();
    const bool hem = std::abs(height) < 1e-12;
    EXPECT_NEAR(std::abs(open.velocities(i)), 9.8 * t, 1e-9) << "vertex " << i;
    if (hem) {
      EXPECT_LT(std::abs(wall.velocities(i)), 1e-12) << "vertex " << i;
    } else if (!g.topology().vertexIsBoundary()[static_cast<size_t>(i)]) {
      EXPECT_EQ(wall.velocities(i), open.velocities(i)) << "vertex " << i;
    }
  }
}

// Along a curved rim the wall keeps tangential flow: on a disc (20 rings,
// rim vertices turn by 2π/#rim, well below the corner angle), u along the
// discrete tangent (the chord between a rim vertex's two rim neighbours,
// which is the circle's tangent on this symmetric rim) is unchanged to
// rounding, an outward radial u is removed, an inward one kept, and a u
// half outward loses exactly its radial part. The fan projection would cut
// the tangential flow by 1 − cos(π/#rim) each step (a drag).
TEST(ExternalForces, BoundaryWallKeepsFlowAlongACurvedRim) {
  StageGeometry g(discMesh(20, 1.0));
  const int n = g.vertexCount();
  const std::vector<char> all;
  const StepContext ctx = contextOnly(0.01, true, false, false);
  int rim = 0;
  for (int i = 0; i < n; ++i) {
    if (!g.topology().vertexIsBoundary()[static_cast<size_t>(i)]) continue;
    ++rim;
    const Vector3 radial = Vector3(g.position(i).x(), g.position(i).y(), 0.0).normalized();
    const Vector3 tangent = Vector3::UnitZ().cross(radial);
    StainState state = zeroState(n);
    for (const Vector3& d : {Vector3(0.3 * tangent), Vector3(-0.3 * tangent), Vector3(-0.2 * radial),
                             Vector3(0.2 * radial), Vector3(0.3 * tangent + 0.2 * radial)}) {
      state.velocities(i) = g.toFrame(i, d);
      applyBoundaryWall(ctx, g.topology(), g.intrinsic, all, state);
      const Vector3 expected = d.dot(radial) > 0.0 ? Vector3(d - d.dot(radial) * radial) : d;
      EXPECT_LT((g.toWorld(i, state.velocities(i)) - expected).norm(), 1e-12) << "vertex " << i;
    }
  }
  EXPECT_GE(rim, 60);
}

}  // namespace
}  // namespace blot::stain
