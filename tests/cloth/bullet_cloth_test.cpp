// Bullet cloth: mesh indices survive into Bullet, the two Bullet traps stay
// avoided (liquid mass never touches rest lengths; the build is O(n)), long
// runs stay sane with the default settings while Bullet's own defaults blow
// up, and pins, collisions, gravity, wind and the coupling inputs do what the
// header says. Float tolerances: Bullet stores single precision, so positions
// carry ~1e-7 relative rounding.
#include <blot/cloth/bullet_cloth.h>

#include "bullet_cloth_testing.h"

#include "flag_fixture.h"

#include <blot/stain/io/mesh_io.h>
#include <blot/stain/geometry/mesh_primitives.h>
#include <blot/stain/geometry/surface_topology.h>
#include <mesh_fixture.h>

#include <gtest/gtest.h>

#include <cmath>
#include <string>

namespace blot::cloth {
namespace {

constexpr double kFrame = 1.0 / 60;
constexpr double kGravity = 9.8;

using test::flatSheet;
using test::hangingFlag;

double totalEnergy(const BulletCloth& cloth) { return cloth.kineticEnergy() + cloth.gravitationalEnergy(); }

Eigen::Vector3d momentum(const BulletCloth& cloth) {
  return (cloth.velocities().array().colwise() * cloth.nodeMasses().array()).colwise().sum().transpose();
}

void expectSameMeshInBullet(const BulletCloth& cloth, const stain::TriangleMesh& mesh) {
  const Eigen::MatrixX3d bodyPositions = BulletClothTesting::bodyPositions(cloth);
  ASSERT_EQ(bodyPositions.rows(), mesh.vertexPositions.rows());
  // Node i holds vertex i, rounded to float (Bullet's precision).
  const Eigen::MatrixX3d rounded = mesh.vertexPositions.cast<float>().cast<double>();
  EXPECT_EQ(bodyPositions, rounded);
  EXPECT_EQ(cloth.positions(), rounded);
  EXPECT_EQ(BulletClothTesting::bodyFaces(cloth), mesh.faces);
  EXPECT_EQ(BulletClothTesting::bodyLinks(cloth), cloth.linkVertices());
  // The first links are our own edge list, in order.
  const stain::SurfaceTopology topology(mesh.faces, static_cast<int>(mesh.vertexPositions.rows()));
  EXPECT_EQ(cloth.linkVertices().topRows(topology.edgeCount()), topology.edgeVertices());
}

TEST(BulletCloth, NodesFacesAndLinksKeepMeshIndices) {
  const stain::TriangleMesh gridMesh = test::jitteredGridMesh(16, 12, 1.5, 1.0, 0.2, 20240611);
  ClothDef grid = test::describeCloth(gridMesh);
  grid.pins = {ClothPin{5, {}}};
  {
    SCOPED_TRACE("jittered grid");
    expectSameMeshInBullet(BulletCloth(grid), gridMesh);
  }
  const stain::TriangleMesh camelMesh = stain::loadMesh(test::externalMesh("camel.off"));
  SCOPED_TRACE("camel.off");
  const BulletCloth cloth(test::describeCloth(camelMesh));
  expectSameMeshInBullet(cloth, camelMesh);
  EXPECT_EQ(cloth.vertexCount(), 9770);
}

TEST(BulletCloth, LumpedMassesFollowVertexAreas) {
  const stain::TriangleMesh mesh = test::jitteredGridMesh(10, 8, 1.0, 0.8, 0.2, 7);
  ClothDef def = test::describeCloth(mesh);
  def.totalMass = 0.3;
  def.pins = {ClothPin{0, {}}};
  const BulletCloth cloth(def);
  // Independent lumped mass: a third of each adjacent triangle's area × density.
  const auto& x = mesh.vertexPositions;
  Eigen::VectorXd area = Eigen::VectorXd::Zero(x.rows());
  for (int f = 0; f < mesh.faces.rows(); ++f) {
    const auto& t = mesh.faces.row(f);
    const Eigen::Vector3d a = x.row(t(0)), b = x.row(t(1)), c = x.row(t(2));
    for (int k = 0; k < 3; ++k) area[t(k)] += (b - a).cross(c - a).norm() / 6;
  }
  const Eigen::VectorXd expected = area * (0.3 / area.sum());
  EXPECT_LT((cloth.nodeMasses() - expected).cwiseAbs().maxCoeff(), 1e-15);
  EXPECT_NEAR(cloth.nodeMasses().sum(), 0.3, 1e-14);
  const Eigen::VectorXd inverse = BulletClothTesting::inverseMasses(cloth);
  EXPECT_EQ(inverse[0], 0.0);  // pinned: infinite mass in Bullet
  for (int i = 1; i < cloth.vertexCount(); ++i) EXPECT_NEAR(inverse[i] * expected[i], 1.0, 1e-6);
  // Energies at rest: no motion; Σ m g z with z = 0.
  EXPECT_EQ(cloth.kineticEnergy(), 0.0);
  EXPECT_EQ(cloth.gravitationalEnergy(), 0.0);
  const BulletCloth flag(hangingFlag(10));
  // Mass-weighted mean height of the symmetric vertical flag is 0.5 m
  // (positions are Bullet's floats).
  EXPECT_NEAR(flag.gravitationalEnergy(), 0.15 * kGravity * 0.5, 1e-7);
}

// Trap 1: btSoftBody::setMass makes the next step reset every rest length to
// the current (stretched) length. setLiquidLoads must leave them bit-exact.
TEST(BulletCloth, ChangingLiquidMassLeavesRestLengthsBitExact) {
  const int cells = 30;
  BulletCloth cloth(hangingFlag(cells));
  BulletCloth control(hangingFlag(cells));
  const Eigen::VectorXd rest = cloth.restLinkLengths();
  ASSERT_EQ(control.restLinkLengths(), rest);
  const int n = cloth.vertexCount();
  const Eigen::MatrixX3d noImpulse = Eigen::MatrixX3d::Zero(n, 3);
  Eigen::VectorXd extra(n);
  for (int step = 0; step < 300; ++step) {
    for (int i = 0; i < n; ++i) extra[i] = cloth.nodeMasses()[i] * (0.5 + 0.5 * std::sin(0.1 * step + i));
    cloth.setLiquidLoads(extra, noImpulse);
    cloth.advance(kFrame);
    BulletClothTesting::setMassesWithBulletSetMass(control, control.nodeMasses() + extra);
    control.advance(kFrame);
  }
  EXPECT_TRUE((cloth.currentLinkRestLengths().array() == rest.array()).all());
  // The link constants were refreshed for the new masses: c0 = (1/mₐ + 1/m_b)/kLST.
  const Eigen::VectorXd inverse = BulletClothTesting::inverseMasses(cloth);
  const Eigen::VectorXd c0 = BulletClothTesting::linkConstants(cloth);
  const auto& links = cloth.linkVertices();
  double worst = 0;
  for (int l = 0; l < links.rows(); ++l) {
    const double stiffness = cloth.linkIsEdge()[static_cast<size_t>(l)] ? 1.0 : cloth.definition().bendStiffness;
    const double expected = (inverse[links(l, 0)] + inverse[links(l, 1)]) / stiffness;
    worst = std::max(worst, std::abs(c0[l] - expected) / expected);
  }
  EXPECT_LT(worst, 1e-6);
  // The control, through setMass, has rebuilt its rest shape from the hanging,
  // stretched cloth: rest lengths moved, mostly up.
  const Eigen::ArrayXd change = (control.currentLinkRestLengths() - rest).array() / rest.array();
  EXPECT_GT(change.abs().maxCoeff(), 1e-2);
  EXPECT_GT(change.mean(), 1e-4);
  EXPECT_TRUE(cloth.isHealthy());
}

// Trap 3: Bullet's own defaults (1 position iteration, no substeps, no damping,
// no tethers) blow a 2.5K flag up within a second of hanging, and Bullet then
// switches the body off without a word. isHealthy() must see both.
TEST(BulletCloth, BulletDefaultSettingsBlowUpAndAreCaught) {
  ClothDef def = hangingFlag(49);
  def.positionIterations = 1;
  def.substeps = 1;
  def.dampingRate = 0;
  def.bendStiffness = 0;
  def.tethers = false;
  BulletCloth cloth(def);
  int firstUnhealthy = -1;
  for (int frame = 1; frame <= 300; ++frame) {
    cloth.advance(kFrame);
    if (firstUnhealthy < 0 && !cloth.isHealthy()) firstUnhealthy = frame;
  }
  EXPECT_GT(firstUnhealthy, 0);
  EXPECT_LT(firstUnhealthy, 120);
  EXPECT_TRUE(BulletClothTesting::isDisabledByBullet(cloth));
  EXPECT_FALSE(cloth.isHealthy());
}

// Long-run sanity with the default settings: healthy at every frame, bounded,
// energy not growing once the swing has settled, nearly at rest after 10 s.
class HangingFlag : public ::testing::TestWithParam<int> {};

TEST_P(HangingFlag, StaysSaneForTenSeconds) {
  const int cells = GetParam();
  BulletCloth cloth(hangingFlag(cells));
  const double restEnergy = totalEnergy(cloth);
  double energyAt300 = 0, maxEnergyAfter300 = -1e300;
  for (int frame = 1; frame <= 600; ++frame) {
    cloth.advance(kFrame);
    ASSERT_TRUE(cloth.isHealthy()) << "frame " << frame;
    if (frame == 300) energyAt300 = totalEnergy(cloth);
    if (frame > 300) maxEnergyAfter300 = std::max(maxEnergyAfter300, totalEnergy(cloth));
  }
  // Hanging only lowers the energy; once settled it must not climb back (it
  // wobbles by ~0.1 mJ as nodes touch their tether limits).
  EXPECT_LT(energyAt300, restEnergy);
  EXPECT_LE(maxEnergyAfter300, energyAt300 + 1e-3 * std::abs(restEnergy));
  EXPECT_LT(cloth.kineticEnergy(), 1e-5);  // J, for a 0.15 kg flag: < 1.2 cm/s rms
  // The 1 m flag hangs from z = 1: its lowest point stays within the 5% tether
  // slack of z = 0 (a 1.118 m geodesic from the corner reaches z = −0.06) and
  // the flag stays in its plane's box.
  const Eigen::AlignedBox3d& box = cloth.boundingBox();
  EXPECT_GT(box.min().z(), -0.07);
  EXPECT_LT(box.max().z(), 1.0 + 1e-6);
  EXPECT_GT(box.min().x(), -0.1);
  EXPECT_LT(box.max().x(), 1.1);
  EXPECT_LT(cloth.maxEdgeStrain(), 0.6);  // next to the corner pins
}

INSTANTIATE_TEST_SUITE_P(Resolutions, HangingFlag, ::testing::Values(49, 99),
                         [](const ::testing::TestParamInfo<int>& param) {
                           return std::to_string((param.param + 1) * (param.param + 1)) + "nodes";
                         });

// Two-way coupling input: a heavy stain in the middle of the flag pulls it down.
TEST(BulletCloth, LiquidMassMakesTheFlagSagMore) {
  const int cells = 30;
  BulletCloth dry(hangingFlag(cells));
  BulletCloth wet(hangingFlag(cells));
  const int n = wet.vertexCount();
  Eigen::VectorXd extra = Eigen::VectorXd::Zero(n);
  std::vector<int> stained;
  for (int i = 0; i < n; ++i) {
    const Eigen::Vector3d p = wet.positions().row(i);
    if ((p - Eigen::Vector3d(0.5, 0, 0.5)).norm() < 0.2) stained.push_back(i);
  }
  for (int i : stained) extra[i] = 2 * 0.15 / static_cast<double>(stained.size());  // twice the cloth's mass
  wet.setLiquidLoads(extra, Eigen::MatrixX3d::Zero(n, 3));
  for (int frame = 0; frame < 240; ++frame) {
    dry.advance(kFrame);
    wet.advance(kFrame);
  }
  double dryZ = 0, wetZ = 0;
  for (int i : stained) {
    dryZ += dry.positions()(i, 2) / static_cast<double>(stained.size());
    wetZ += wet.positions()(i, 2) / static_cast<double>(stained.size());
  }
  RecordProperty("stain_sag_mm", std::to_string(1000 * (dryZ - wetZ)));
  EXPECT_GT(dryZ - wetZ, 0.005);  // m (measured 12 mm)
  EXPECT_TRUE(wet.isHealthy());
}

TEST(BulletCloth, AnimatedPinsFollowTheirTrajectories) {
  const int cells = 20;
  ClothDef def = hangingFlag(cells);
  def.pins[0].motion.amplitude = Eigen::Vector3d(0, 0.1, 0.05);
  def.pins[0].motion.frequency = 1.5;
  def.pins[0].motion.phase = 0.3;
  def.pins[1].motion.velocity = Eigen::Vector3d(-0.2, 0, 0);
  BulletCloth cloth(def);
  const double restNeighbourY = cloth.positions()(test::flagTopLeft(cells) - (cells + 1), 1);
  double maxNeighbourY = 0;
  for (int frame = 1; frame <= 120; ++frame) {
    cloth.advance(kFrame);
    for (const ClothPin& pin : def.pins) {
      const Eigen::Vector3d rest = def.restPositions.row(pin.vertex);
      const Eigen::Vector3d target = pin.motion.position(rest, cloth.time());
      EXPECT_LT((cloth.positions().row(pin.vertex).transpose() - target).norm(), 1e-5) << "frame " << frame;
      EXPECT_EQ(cloth.velocities().row(pin.vertex).transpose(), pin.motion.velocityAt(cloth.time()));
    }
    maxNeighbourY = std::max(maxNeighbourY, std::abs(cloth.positions()(test::flagTopLeft(cells) - (cells + 1), 1)));
  }
  EXPECT_NEAR(cloth.positions()(test::flagTopRight(cells), 0), 1.0 - 0.2 * 2.0, 1e-5);
  // The cloth follows the waving corner: the vertex below it swings too.
  EXPECT_GT(maxNeighbourY - restNeighbourY, 0.03);
  EXPECT_TRUE(cloth.isHealthy());
}

TEST(BulletCloth, ReleasedPinsDropTheCloth) {
  const int cells = 20;
  ClothDef def = hangingFlag(cells);
  for (ClothPin& pin : def.pins) pin.motion.releaseTime = 0.5;
  BulletCloth cloth(def);
  for (int frame = 1; frame <= 30; ++frame) cloth.advance(kFrame);  // t = 0.5 s
  EXPECT_TRUE(cloth.isPinned(test::flagTopLeft(cells)));
  EXPECT_NEAR(cloth.positions()(test::flagTopLeft(cells), 2), 1.0, 1e-6);
  for (int frame = 1; frame <= 30; ++frame) cloth.advance(kFrame);  // t = 1 s
  EXPECT_FALSE(cloth.isPinned(test::flagTopLeft(cells)));
  EXPECT_GT(BulletClothTesting::inverseMasses(cloth)[test::flagTopLeft(cells)], 0);
  // Free fall for 0.5 s: ½ g t² = 1.23 m (a little less with damping).
  EXPECT_LT(cloth.positions()(test::flagTopLeft(cells), 2), 1.0 - 1.1);
  EXPECT_LT(cloth.positions()(test::flagTopRight(cells), 2), 1.0 - 1.1);
}

// setPinTarget: the pin travels in a straight line to its target during one
// advance, is held there, and drags the cloth;
// a state captured after the move continues bit-identically; a released pin
// cannot be moved.
TEST(BulletCloth, PinMovedAtRuntimeDragsTheCloth) {
  const int cells = 16;
  const int pin = test::flagTopLeft(cells), below = pin - (cells + 1);
  ClothDef def = hangingFlag(cells);
  def.pins[1].motion.releaseTime = 0.1;
  BulletCloth cloth(def), still(def);
  for (int frame = 0; frame < 10; ++frame) {
    cloth.advance(kFrame);
    still.advance(kFrame);
  }
  const Eigen::Vector3d start = cloth.positions().row(pin).transpose();
  const Eigen::Vector3d target = start + Eigen::Vector3d(0.2, 0.3, -0.1);
  cloth.setPinTarget(pin, target);
  cloth.advance(kFrame);
  EXPECT_LT((cloth.positions().row(pin).transpose() - target).norm(), 1e-6);
  const BulletClothState kept = cloth.captureState();
  for (int frame = 0; frame < 60; ++frame) {
    cloth.advance(kFrame);
    still.advance(kFrame);
  }
  EXPECT_LT((cloth.positions().row(pin).transpose() - target).norm(), 1e-6) << "held";
  EXPECT_GT(cloth.positions()(below, 1) - still.positions()(below, 1), 0.15) << "the cloth follows";
  EXPECT_TRUE(cloth.isHealthy());
  BulletCloth resumed(def);
  resumed.restoreState(kept);
  for (int frame = 0; frame < 60; ++frame) resumed.advance(kFrame);
  EXPECT_EQ(resumed.positions(), cloth.positions());
  EXPECT_THROW(cloth.setPinTarget(test::flagTopRight(cells), target), std::invalid_argument);  // released
  EXPECT_THROW(cloth.setPinTarget(below, target), std::invalid_argument);                      // no pin
}

TEST(BulletCloth, GravityIsSetInBothPlacesAndDrivesFreeFall) {
  ClothDef def = flatSheet(10, 2.0);
  def.gravity = Eigen::Vector3d(0.5, -1.0, -3.0);
  def.dampingRate = 0;
  BulletCloth cloth(def);
  const Eigen::Vector3d g = def.gravity.cast<float>().cast<double>();
  EXPECT_EQ(BulletClothTesting::worldGravity(cloth), g);
  EXPECT_EQ(BulletClothTesting::softBodyWorldInfoGravity(cloth), g);
  const Eigen::Vector3d start = cloth.positions().colwise().mean();
  const int frames = 30, substeps = def.substeps;
  for (int frame = 0; frame < frames; ++frame) cloth.advance(kFrame);
  // Semi-implicit Euler with k = frames·substeps steps of hₛ: v = g k hₛ and
  // x = x₀ + g hₛ² k(k+1)/2, exactly, whatever the links do.
  const double hs = kFrame / substeps;
  const double k = frames * substeps;
  // Bullet recomputes v = (x − x_prev)/hₛ from float positions every substep:
  // ~ulp(x)/hₛ = 6e-5 m/s of rounding per step, a random walk over 120 steps.
  const Eigen::Vector3d velocity = cloth.velocities().colwise().mean();
  EXPECT_LT((velocity - g * k * hs).norm(), 2e-3 * (g * k * hs).norm());
  const Eigen::Vector3d drop = Eigen::Vector3d(cloth.positions().colwise().mean()) - start;
  EXPECT_LT((drop - g * hs * hs * k * (k + 1) / 2).norm(), 5e-4);
}

TEST(BulletCloth, ImpulsesChangeMomentumByTheirSumAndSkipPins) {
  ClothDef def = flatSheet(12, 0);
  def.gravity.setZero();
  def.dampingRate = 0;
  BulletCloth cloth(def);
  const int n = cloth.vertexCount();
  Eigen::VectorXd extra(n);
  Eigen::MatrixX3d impulses(n, 3);
  for (int i = 0; i < n; ++i) {
    extra[i] = 1e-4 * (1 + std::sin(i));
    impulses.row(i) << 1e-4 * std::cos(0.7 * i), 2e-4 * std::sin(1.3 * i), 5e-5;
  }
  cloth.setLiquidLoads(extra, impulses);
  cloth.advance(kFrame);
  const Eigen::Vector3d expected = impulses.colwise().sum();
  EXPECT_LT((momentum(cloth) - expected).norm(), 2e-4 * expected.norm());  // float velocities
  EXPECT_NEAR(cloth.nodeMasses().sum(), def.totalMass + extra.sum(), 1e-14);

  ClothDef pinned = def;
  pinned.pins = {ClothPin{0, {}}};
  BulletCloth held(pinned);
  held.setLiquidLoads(extra, impulses);
  held.advance(kFrame);
  EXPECT_EQ(held.velocities().row(0).norm(), 0.0);
  EXPECT_EQ(held.positions().row(0), held.definition().restPositions.row(0));
}

TEST(BulletCloth, GroundPlaneStopsADroppedCloth) {
  ClothDef def = flatSheet(20, 0.3);
  def.colliders = {ClothCollider::plane(Eigen::Vector3d(0, 0, 0), Eigen::Vector3d::UnitZ())};
  BulletCloth cloth(def);
  double lowest = 1;
  for (int frame = 0; frame < 120; ++frame) {
    cloth.advance(kFrame);
    lowest = std::min(lowest, cloth.boundingBox().min().z());
  }
  const double margin = cloth.collisionMargin();
  EXPECT_GT(lowest, 0.0);                                // never sinks in
  EXPECT_LT(cloth.boundingBox().max().z(), 2 * margin);  // lies on the ground
  // Resting contact chatters (Bullet turns the push-out into velocity):
  // ~2 cm/s, so KE ~ 3e-5 J for this 0.15 kg sheet; far below the 0.44 J of
  // the fall it stopped.
  EXPECT_LT(cloth.kineticEnergy(), 1e-4);
  EXPECT_TRUE(cloth.isHealthy());
}

TEST(BulletCloth, SphereAndTableHoldTheClothOutside) {
  ClothDef def = flatSheet(30, 0.5);
  const Eigen::Vector3d center(0.5, 0.5, 0.2);
  const double radius = 0.2;
  def.colliders = {ClothCollider::sphere(center, radius),
                   ClothCollider::box(Eigen::Vector3d(0.5, 0.5, -0.5), Eigen::Vector3d(0.6, 0.6, 0.5)),
                   ClothCollider::plane(Eigen::Vector3d(0, 0, -1.5), Eigen::Vector3d::UnitZ())};
  BulletCloth cloth(def);
  for (int frame = 0; frame < 90; ++frame) cloth.advance(kFrame);
  double sphereClearance = 1, tableClearance = 1;
  for (int i = 0; i < cloth.vertexCount(); ++i) {
    const Eigen::Vector3d p = cloth.positions().row(i);
    sphereClearance = std::min(sphereClearance, (p - center).norm() - radius);
    const Eigen::Vector3d inside = (p - Eigen::Vector3d(0.5, 0.5, -0.5)).cwiseAbs() - Eigen::Vector3d(0.6, 0.6, 0.5);
    if (inside.maxCoeff() < 0) tableClearance = std::min(tableClearance, inside.maxCoeff());
  }
  EXPECT_GT(sphereClearance, -2e-3);  // m: the sparse distance field's interpolation error
  EXPECT_EQ(tableClearance, 1.0);     // no node inside the table
  // The cloth drapes over the sphere: its top rests on it.
  EXPECT_NEAR(cloth.boundingBox().max().z(), center.z() + radius + cloth.collisionMargin(), 0.01);
  EXPECT_TRUE(cloth.isHealthy());
}

// A collider far smaller than Bullet's float positions resolve: its
// automatic voxel (a quarter of its size, 2.5e-13 m) overflowed the cache's
// int cell index and crashed in btSoftBody::checkContact. The voxel stops at
// kMinCollisionVoxelSize; the cloth falls past the speck.
TEST(BulletCloth, ASpeckOfAColliderDoesNotCrashTheContacts) {
  ClothDef def = flatSheet(12, 0.5);
  def.colliders = {ClothCollider::sphere(Eigen::Vector3d(0.5, 0.5, 0.2), 1e-12),
                   ClothCollider::box(Eigen::Vector3d(0.3, 0.3, 0.1), Eigen::Vector3d::Constant(1e-20))};
  BulletCloth cloth(def);
  for (int frame = 0; frame < 30; ++frame) cloth.advance(kFrame);
  EXPECT_TRUE(cloth.isHealthy());
  EXPECT_LT(cloth.boundingBox().max().z(), 0.5);
}

TEST(BulletCloth, WindDragsTheClothAlong) {
  ClothDef def = flatSheet(12, 0);
  def.gravity.setZero();
  def.dampingRate = 0;
  def.wind.velocity = Eigen::Vector3d(0, 0, 4);
  def.wind.dragCoefficient = 1;
  BulletCloth cloth(def);
  for (int frame = 0; frame < 30; ++frame) cloth.advance(kFrame);
  const Eigen::Vector3d velocity = momentum(cloth) / def.totalMass;
  EXPECT_GT(velocity.z(), 0.5);  // pushed along the wind, normal to the sheet
  EXPECT_LT(velocity.z(), 4.0);  // never faster than the air
  EXPECT_LT(std::abs(velocity.x()) + std::abs(velocity.y()), 0.05 * velocity.z());  // measured 0.8%
}

TEST(BulletCloth, RunsAreDeterministic) {
  ClothDef def = hangingFlag(16);
  def.pins[0].motion.amplitude = Eigen::Vector3d(0, 0.2, 0);
  def.pins[0].motion.frequency = 2;
  def.colliders = {ClothCollider::sphere(Eigen::Vector3d(0.5, 0.15, 0.4), 0.1)};
  BulletCloth first(def), second(def);
  for (int frame = 0; frame < 60; ++frame) {
    first.advance(kFrame);
    second.advance(kFrame);
  }
  EXPECT_EQ(first.positions(), second.positions());
  BulletCloth moved(std::move(first));
  moved.advance(kFrame);
  second.advance(kFrame);
  EXPECT_EQ(moved.positions(), second.positions());
}

// Trap 2: CreateFromTriMesh's #V² table (3 s and 1.2 GB at 35K vertices, an
// int overflow past 46K). A 140K build would need ~78 GB that way; ours is
// O(n) and keeps every index. The build time is in tests/bench (no timed tests).
TEST(BulletCloth, BuildsA140KVertexGridWithIndicesPreserved) {
  const ClothDef def = test::describeCloth(stain::gridMesh(373, 373, 2.0, 2.0));
  const BulletCloth cloth(def);
  EXPECT_EQ(cloth.vertexCount(), 139876);
  EXPECT_EQ(BulletClothTesting::bodyFaces(cloth), def.faces);
  // Node i starts at vertex i (to Bullet's single precision).
  EXPECT_LT((cloth.positions() - def.restPositions).cwiseAbs().maxCoeff(), 1e-6);
}

TEST(BulletCloth, InvalidDefinitionsNameTheField) {
  auto message = [](const ClothDef& def) {
    try {
      BulletCloth cloth(def);
    } catch (const std::invalid_argument& e) {
      return std::string(e.what());
    }
    return std::string("no error");
  };
  ClothDef def = hangingFlag(4);
  def.totalMass = 0;
  EXPECT_NE(message(def).find("totalMass"), std::string::npos);
  EXPECT_NE(message(ClothDef{}).find("restPositions is empty"), std::string::npos) << message(ClothDef{});
  def = hangingFlag(4);
  def.pins.push_back(ClothPin{1000, {}});
  EXPECT_NE(message(def).find("pins[2].vertex"), std::string::npos);
  def = hangingFlag(4);
  def.pins.push_back(def.pins[0]);
  EXPECT_NE(message(def).find("pinned twice"), std::string::npos);
  def = hangingFlag(4);
  def.colliders = {ClothCollider::sphere(Eigen::Vector3d::Zero(), 0)};
  EXPECT_NE(message(def).find("colliders[0].radius"), std::string::npos);
  def = hangingFlag(4);
  def.substeps = 0;
  EXPECT_NE(message(def).find("substeps"), std::string::npos);
  // Below a float inverse mass for the lightest node, or a voxel whose cell
  // index overflows int (both crashed or failed unrecoverably in a step).
  def = hangingFlag(4);
  def.totalMass = 1e-38;
  EXPECT_NE(message(def).find("totalMass = 1e-38 kg gives the lightest node"), std::string::npos) << message(def);
  def = hangingFlag(4);
  def.collisionVoxelSize = 1e-20;
  EXPECT_NE(message(def).find("collisionVoxelSize must be 0 (automatic) or in [0.001, inf) m, got 1e-20"),
            std::string::npos)
      << message(def);
  // The mesh arrays: each error names the field and the row.
  def = hangingFlag(4);
  def.faces(3, 1) = 25;
  EXPECT_NE(message(def).find("faces[3] has vertex 25 outside [0, 25)"), std::string::npos) << message(def);
  def = hangingFlag(4);
  def.faces(2, 2) = def.faces(2, 0);
  EXPECT_NE(message(def).find("faces[2] repeats a vertex"), std::string::npos) << message(def);
  def = hangingFlag(4);
  def.edges(7, 1) = def.edges(7, 0);
  EXPECT_NE(message(def).find("edges[7] joins vertex"), std::string::npos) << message(def);
  def = hangingFlag(4);
  def.bendingPairs(0, 0) = -1;
  EXPECT_NE(message(def).find("bendingPairs[0]"), std::string::npos) << message(def);
  def = hangingFlag(4);
  def.restPositions(6, 2) = std::nan("");
  EXPECT_NE(message(def).find("restPositions[6] is not finite"), std::string::npos) << message(def);
  def = hangingFlag(4);
  def.uvs.conservativeResize(24, 2);
  EXPECT_NE(message(def).find("uvs has 24 rows"), std::string::npos) << message(def);
  def = hangingFlag(4);
  def.nodeAreas[9] = -1e-3;
  EXPECT_NE(message(def).find("nodeAreas[9]"), std::string::npos) << message(def);
  def = hangingFlag(4);
  def.nodeAreas.resize(3);
  EXPECT_NE(message(def).find("nodeAreas has 3 entries; expected 25"), std::string::npos) << message(def);

  BulletCloth cloth(hangingFlag(4));
  EXPECT_THROW(cloth.advance(0), std::invalid_argument);
  EXPECT_THROW(cloth.setLiquidLoads(Eigen::VectorXd::Zero(3), Eigen::MatrixX3d::Zero(3, 3)), std::invalid_argument);
  EXPECT_THROW(cloth.setLiquidLoads(Eigen::VectorXd::Constant(25, -1), Eigen::MatrixX3d::Zero(25, 3)),
               std::invalid_argument);
}

}  // namespace
}  // namespace blot::cloth
