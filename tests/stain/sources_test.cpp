// Tests for drops and held regions (stain/src/stages/sources.cpp): exact masses, the
// bump's shape and footprint, velocity projection and momentum, splash
// determinism, input validation naming the field, and held regions.
#include <blot/stain/stages/sources.h>
#include <gtest/gtest.h>

#include <cmath>
#include <limits>
#include <stdexcept>
#include <string>
#include <vector>

#include "stain_fixture.h"

namespace blot::stain {
namespace {

using namespace liquid_testing;

struct DropMesh : ::testing::Test {
  const int n = 40;
  LiquidMesh g{gridMesh(n, n, 1, 1), isotropicFabric(2 * n * n)};
  StainState state = zeroState(g.vertexCount());
  void add(const DropDef& drop) { addDrop(drop, g.topology, g.intrinsic, g.extrinsic, state); }
  // Tangent velocity of vertex i as a world vector.
  Vector3 world(int i) const {
    const Matrix3& f = g.extrinsic.frames[static_cast<size_t>(i)];
    return f.col(0) * state.velocities[i].real() + f.col(1) * state.velocities[i].imag();
  }
  int nearest(const Vector3& p) const {
    int best = 0;
    for (int i = 1; i < g.vertexCount(); ++i) {
      if ((g.position(i) - p).norm() < (g.position(best) - p).norm()) best = i;
    }
    return best;
  }
};

TEST_F(DropMesh, MassesAreExactAndTheBumpIsSmoothAndCompact) {
  DropDef drop;
  drop.centerPoint = Vector3(0.512, 0.493, 0.0);
  drop.radius = 0.15;
  drop.solventMass = 2e-3;
  drop.soluteMass = 3e-4;
  add(drop);
  const double solvent = totalMass(g.areas(), state.solvent), solute = totalMass(g.areas(), state.solute);
  std::printf("  drop: solvent %.17g kg (asked 2e-3), solute %.17g kg (asked 3e-4)\n", solvent, solute);
  EXPECT_NEAR(solvent, 2e-3, 1e-15 * 2e-3);
  EXPECT_NEAR(solute, 3e-4, 1e-15 * 3e-4);
  EXPECT_EQ(state.addedSolvent, 2e-3);
  EXPECT_EQ(state.addedSolute, 3e-4);

  const int center = nearest(drop.centerPoint);
  Eigen::Index peak;
  state.solvent.maxCoeff(&peak);
  EXPECT_EQ(peak, center);
  int inside = 0;
  for (int i = 0; i < g.vertexCount(); ++i) {
    const double d = (g.position(i) - drop.centerPoint).norm();
    EXPECT_GE(state.solvent[i], 0.0);
    if (d >= drop.radius) {
      EXPECT_EQ(state.solvent[i], 0.0) << "vertex " << i << " outside the radius";
    } else {
      ++inside;
      // The bump (1 − d²/R²)² up to a common factor: check its shape.
      const double w = (1 - d * d / (drop.radius * drop.radius)) * (1 - d * d / (drop.radius * drop.radius));
      const double dc = (g.position(center) - drop.centerPoint).norm() / drop.radius;
      EXPECT_NEAR(state.solvent[i] / state.solvent[center], w / ((1 - dc * dc) * (1 - dc * dc)), 1e-12);
      EXPECT_NEAR(state.solute[i] / state.solvent[i], 0.15, 1e-14);
    }
  }
  EXPECT_GT(inside, 100);  // π R² / dx² ≈ 113

  // A second drop adds on top, and the budget keeps counting.
  add(drop);
  EXPECT_NEAR(totalMass(g.areas(), state.solvent), 4e-3, 1e-15 * 4e-3);
  EXPECT_EQ(state.addedSolvent, 4e-3);
}

TEST_F(DropMesh, ARadiusBelowTheMeshSpacingPutsTheWholeDropOnTheCentreVertex) {
  DropDef drop;
  drop.centerVertex = 5 * (n + 1) + 7;
  drop.radius = 1e-4;
  drop.solventMass = 1e-3;
  drop.soluteMass = 0.0;
  add(drop);
  EXPECT_DOUBLE_EQ(state.solvent[drop.centerVertex] * g.areas()[drop.centerVertex], 1e-3);
  EXPECT_EQ((state.solvent.array() > 0).count(), 1);
  EXPECT_TRUE((state.solute.array() == 0).all());
}

TEST_F(DropMesh, ARadiusThatChangesInItsLastBitWetsTheSameVertices) {
  // Radius = the distance to a grid vertex: with it the vertex is outside
  // (d < R fails); one ulp larger it is inside, at a bump of ~1e-32 of the
  // peak: no liquid (kDropProfileFloor), so both drops wet the same vertices
  // with the same liquid to rounding.
  DropDef drop;
  drop.centerVertex = 20 * (n + 1) + 20;
  const int rim = 23 * (n + 1) + 24;  // (3, 4) cells away: 5 cells
  drop.radius = (g.position(rim) - g.position(drop.centerVertex)).norm();
  drop.solventMass = 1e-3;
  drop.soluteMass = 1e-4;
  add(drop);
  const StainState exact = state;
  state = zeroState(g.vertexCount());
  drop.radius = std::nextafter(drop.radius, 1.0);
  add(drop);
  EXPECT_EQ(state.solvent[rim], 0.0);
  EXPECT_TRUE(((state.solvent.array() > 0) == (exact.solvent.array() > 0)).all());
  EXPECT_LT((state.solvent - exact.solvent).cwiseAbs().maxCoeff(), 1e-14 * exact.solvent.maxCoeff());
  EXPECT_LT((state.solute - exact.solute).cwiseAbs().maxCoeff(), 1e-14 * exact.solute.maxCoeff());
  // The floor removes no real liquid: a vertex at 0.999 R keeps its share.
  state = zeroState(g.vertexCount());
  drop.radius *= 1.001;
  add(drop);
  EXPECT_GT(state.solvent[rim], 0.0);
  EXPECT_NEAR(totalMass(g.areas(), state.solvent), 1e-3, 1e-15);
}

TEST_F(DropMesh, VelocityIsProjectedIntoTheFramesAndMomentumIsConserved) {
  // Liquid already there, moving along x; a drop moving along y (and down,
  // which the surface absorbs: only the tangential part is kept).
  const Vector3 old(0.4, 0.0, 0.0), incoming(0.0, 1.0, -3.0);
  state.solvent.setConstant(0.5);
  for (int i = 0; i < g.vertexCount(); ++i) {
    const Matrix3& f = g.extrinsic.frames[static_cast<size_t>(i)];
    state.velocities[i] = Complex(old.dot(f.col(0)), old.dot(f.col(1)));
  }
  auto momentum = [&] {
    Vector3 p = Vector3::Zero();
    for (int i = 0; i < g.vertexCount(); ++i) p += g.areas()[i] * state.solvent[i] * world(i);
    return p;
  };
  const Vector3 before = momentum();
  DropDef drop;
  drop.centerVertex = 20 * (n + 1) + 20;
  drop.radius = 0.2;
  drop.solventMass = 0.01;
  drop.velocity = incoming;
  add(drop);
  const Vector3 expected = before + drop.solventMass * Vector3(incoming.x(), incoming.y(), 0.0);
  std::printf("  momentum after the drop (%.12f, %.12f, %.12f), expected (%.12f, %.12f, 0)\n", momentum().x(),
              momentum().y(), momentum().z(), expected.x(), expected.y());
  EXPECT_NEAR((momentum() - expected).norm(), 0.0, 1e-15);
  EXPECT_NEAR(world(drop.centerVertex).z(), 0.0, 1e-15);
  // Outside the drop nothing changed.
  EXPECT_NEAR((world(0) - old).norm(), 0.0, 1e-15);
}

TEST_F(DropMesh, SplashIsOutgoingDeterministicBySeedAndDifferentAcrossSeeds) {
  DropDef drop;
  drop.centerVertex = 20 * (n + 1) + 20;
  drop.radius = 0.25;
  drop.solventMass = 1e-3;
  drop.splashSpeed = 0.5;
  drop.splashSeed = 1234;
  add(drop);
  const ComplexVector first = state.velocities;

  state = zeroState(g.vertexCount());
  add(drop);
  EXPECT_TRUE((state.velocities.array() == first.array()).all()) << "same seed, same splash, bit for bit";

  int outgoing = 0, footprint = 0;
  double slowest = 1e9, fastest = 0;
  for (int i = 0; i < g.vertexCount(); ++i) {
    if (state.solvent[i] == 0.0 || i == drop.centerVertex) continue;
    ++footprint;
    const Vector3 radial = g.position(i) - g.position(drop.centerVertex);
    const Vector3 v = world(i);
    outgoing += v.dot(radial) > 0 ? 1 : 0;
    const double atRim = v.norm() / (radial.norm() / drop.radius);  // speed / (r/R)
    slowest = std::min(slowest, atRim);
    fastest = std::max(fastest, atRim);
    EXPECT_NEAR(v.normalized().dot(radial.normalized()), 1.0, 1e-12) << "radial, vertex " << i;
  }
  EXPECT_EQ(state.velocities[drop.centerVertex], Complex(0, 0));
  EXPECT_EQ(outgoing, footprint);
  std::printf("  splash (seed 1234): %d vertices, rim speed between %.3f and %.3f m/s (nominal 0.5)\n",
              footprint, slowest, fastest);
  EXPECT_GT(slowest, 0.5 * 0.08);
  EXPECT_LT(fastest, 0.5 * 1.92);
  EXPECT_GT(fastest / slowest, 1.2) << "the angular modulation is visible";

  state = zeroState(g.vertexCount());
  drop.splashSeed = 1235;
  add(drop);
  const double difference = (state.velocities - first).cwiseAbs().maxCoeff();
  std::printf("  seeds 1234 vs 1235: max velocity difference %.3f m/s\n", difference);
  EXPECT_GT(difference, 0.01);
}

TEST(DropFootprint, ADropOnAFoldedClothDoesNotJumpToTheLayerAbove) {
  // A strip folded back over itself at x = 1, the upper layer 2 cm above.
  TriangleMesh mesh = gridMesh(40, 10, 2.0, 0.5);
  for (Eigen::Index v = 0; v < mesh.vertexPositions.rows(); ++v) {
    const double x = mesh.vertexPositions(v, 0);
    if (x > 1.0)
      mesh.vertexPositions.row(v) << 2.0 - x, mesh.vertexPositions(v, 1),
          0.02 * std::min(1.0, (x - 1.0) / 0.05);
  }
  const LiquidMesh g(std::move(mesh), isotropicFabric(2 * 40 * 10));
  StainState state = zeroState(g.vertexCount());
  DropDef drop;
  drop.centerPoint = Vector3(0.85, 0.25, 0.0);
  drop.radius = 0.1;
  drop.solventMass = 1e-3;
  addDrop(drop, g.topology, g.intrinsic, g.extrinsic, state);
  int upper = 0, lower = 0, upperWithinRadius = 0;
  for (int i = 0; i < g.vertexCount(); ++i) {
    const bool isUpper = g.position(i).z() > 0.01;
    if ((g.position(i) - drop.centerPoint).norm() < drop.radius && isUpper) ++upperWithinRadius;
    if (state.solvent[i] > 0) (isUpper ? upper : lower) += 1;
  }
  EXPECT_GT(upperWithinRadius, 0) << "the test needs upper-layer vertices inside the radius";
  EXPECT_EQ(upper, 0);
  // The centre and its eight neighbours; the four grid vertices at R (to
  // rounding) stay dry (kDropProfileFloor).
  EXPECT_EQ(lower, 9);
  EXPECT_NEAR(totalMass(g.areas(), state.solvent), 1e-3, 1e-18);
}

TEST_F(DropMesh, BadDropFieldsAreRejectedNamingTheFieldAndLeaveTheStateAlone) {
  const double nan = std::numeric_limits<double>::quiet_NaN(), inf = std::numeric_limits<double>::infinity();
  struct Case {
    const char* field;
    DropDef drop;
  };
  std::vector<Case> cases;
  auto make = [](auto change) {
    DropDef d;
    d.centerVertex = 3;
    change(d);
    return d;
  };
  cases.push_back({"centerVertex", make([&](DropDef& d) { d.centerVertex = 100000; })});
  cases.push_back({"centerVertex", make([&](DropDef& d) { d.centerVertex = -2; })});
  cases.push_back({"centerPoint", make([&](DropDef& d) {
                     d.centerVertex = -1;
                     d.centerPoint.x() = nan;
                   })});
  cases.push_back({"radius", make([&](DropDef& d) { d.radius = 0.0; })});
  cases.push_back({"radius", make([&](DropDef& d) { d.radius = -1.0; })});
  cases.push_back({"radius", make([&](DropDef& d) { d.radius = nan; })});
  cases.push_back({"solventMass", make([&](DropDef& d) { d.solventMass = -1e-3; })});
  cases.push_back({"solventMass", make([&](DropDef& d) { d.solventMass = inf; })});
  cases.push_back({"soluteMass", make([&](DropDef& d) { d.soluteMass = -1e-9; })});
  cases.push_back({"soluteMass", make([&](DropDef& d) { d.soluteMass = nan; })});
  cases.push_back({"velocity", make([&](DropDef& d) { d.velocity.y() = inf; })});
  cases.push_back({"splashSpeed", make([&](DropDef& d) { d.splashSpeed = -0.1; })});
  cases.push_back({"splashSpeed", make([&](DropDef& d) { d.splashSpeed = nan; })});
  for (const Case& c : cases) {
    try {
      add(c.drop);
      ADD_FAILURE() << "accepted a bad " << c.field;
    } catch (const std::invalid_argument& e) {
      const std::string message = e.what();
      EXPECT_NE(message.find(std::string("DropDef::") + c.field), std::string::npos) << message;
    }
  }
  std::printf("  e.g. \"%s\"\n",
              [&] {
                try {
                  add(cases[0].drop);
                } catch (const std::invalid_argument& e) {
                  return std::string(e.what());
                }
                return std::string();
              }()
                  .c_str());
  EXPECT_TRUE((state.solvent.array() == 0).all());
  EXPECT_EQ(state.addedSolvent, 0.0);
}

TEST_F(DropMesh, HeldRegionsFillUpToTheirDensitiesAndRecordWhatWasAdded) {
  HeldRegion region;
  region.vertices = {0, 1, 2, 41, 42, 42};  // a duplicate must not count twice
  region.solventDensity = 2.0;
  region.soluteDensity = 0.3;
  state.solvent[1] = 5.0;  // already above: untouched
  state.solvent[2] = 1.0;  // half-full, moving
  state.velocities[2] = Complex(0.2, -0.1);
  const std::vector<HeldRegion> regions = {region};
  PhysicsSwitches switches;
  StepContext ctx = makeStepContext(0.01, Vector3(0, 0, -9.8), switches, LiquidParameters{});

  applySources(ctx, regions, g.intrinsic, state);
  const Vector& A = g.areas();
  EXPECT_EQ(state.solvent[0], 2.0);
  EXPECT_EQ(state.solvent[1], 5.0);
  EXPECT_EQ(state.solvent[2], 2.0);
  EXPECT_EQ(state.solute[42], 0.3);
  EXPECT_EQ(state.velocities[2], Complex(0.1, -0.05)) << "the added liquid is at rest: momentum kept";
  const double added = 2.0 * A[0] + 1.0 * A[2] + 2.0 * A[41] + 2.0 * A[42];
  EXPECT_NEAR(state.addedSolvent, added, 1e-15 * added);
  EXPECT_NEAR(state.addedSolvent, totalMass(A, state.solvent) - (5.0 * A[1] + 1.0 * A[2]), 1e-15);

  // Held: a second call adds nothing; switched off: nothing happens.
  const double addedBefore = state.addedSolvent;
  applySources(ctx, regions, g.intrinsic, state);
  EXPECT_EQ(state.addedSolvent, addedBefore);
  state.solvent[0] = 0.5;
  ctx.switches.sources = false;
  applySources(ctx, regions, g.intrinsic, state);
  EXPECT_EQ(state.solvent[0], 0.5);
}

}  // namespace
}  // namespace blot::stain
