// Long runs of the Bullet cloth at demo sizes (label "study": minutes, not CI).
// With the ClothDef defaults a 35K-node flag hanging from two corners, the same
// flag waving, and a 10K sheet draped over a sphere on the ground stay healthy
// for 30 simulated seconds: finite, bounded, energy flat once settled, no
// Bullet-disabled body. docs/cloth.md has the numbers these bounds come from.
#include <blot/cloth/bullet_cloth.h>
#include <blot/coupling/coupled_surface.h>
#include <blot/stain/geometry/mesh_primitives.h>
#include <blot/stain/geometry/surface_topology.h>

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <vector>

namespace blot::cloth {
namespace {

constexpr double kFrame = 1.0 / 60;
constexpr int kFrames = 1800;  // 30 s

ClothDef describe(const stain::TriangleMesh& mesh) {
  ClothDef def;
  coupling::describeClothMesh(mesh, stain::SurfaceTopology(mesh.faces, static_cast<int>(mesh.vertexPositions.rows())),
                              def);
  return def;
}

ClothDef flag(int cells, bool waving) {
  stain::TriangleMesh mesh = stain::gridMesh(cells, cells, 1.0, 1.0);
  for (int i = 0; i < mesh.vertexPositions.rows(); ++i) {
    const double x = mesh.vertexPositions(i, 0), y = mesh.vertexPositions(i, 1);
    mesh.vertexPositions.row(i) << x, 0, y;
  }
  ClothDef def = describe(mesh);
  PinMotion motion;
  if (waving) {
    motion.amplitude = Eigen::Vector3d(0, 0.1, 0);  // 10 cm at 1 Hz, across the flag
    motion.frequency = 1.0;
  }
  def.pins = {ClothPin{cells * (cells + 1), motion}, ClothPin{cells * (cells + 1) + cells, motion}};
  return def;
}

double strainPercentile(const BulletCloth& cloth, double q) {
  std::vector<double> strains;
  const auto& links = cloth.linkVertices();
  for (int l = 0; l < links.rows(); ++l) {
    if (!cloth.linkIsEdge()[static_cast<size_t>(l)]) continue;
    const double length = (cloth.positions().row(links(l, 0)) - cloth.positions().row(links(l, 1))).norm();
    strains.push_back(length / cloth.restLinkLengths()[l] - 1);
  }
  std::sort(strains.begin(), strains.end());
  return strains[static_cast<size_t>(q * static_cast<double>(strains.size() - 1))];
}

struct RunSummary {
  double energyMid = 0, maxEnergySecondHalf = -1e300, lowest = 1e300;
};

RunSummary run(BulletCloth& cloth) {
  RunSummary summary;
  for (int frame = 1; frame <= kFrames; ++frame) {
    cloth.advance(kFrame);
    EXPECT_TRUE(cloth.isHealthy()) << "frame " << frame;
    if (!cloth.isHealthy()) break;
    const double energy = cloth.kineticEnergy() + cloth.gravitationalEnergy();
    if (frame == kFrames / 2) summary.energyMid = energy;
    if (frame > kFrames / 2) summary.maxEnergySecondHalf = std::max(summary.maxEnergySecondHalf, energy);
    summary.lowest = std::min(summary.lowest, cloth.boundingBox().min().z());
  }
  return summary;
}

TEST(BulletClothLongRun, HangingFlag35KNodes) {
  BulletCloth cloth(flag(186, false));
  const RunSummary summary = run(cloth);
  // Settled: energy flat (measured equal to 5 digits), nearly at rest.
  EXPECT_LE(summary.maxEnergySecondHalf, summary.energyMid + 1e-3);
  EXPECT_LT(cloth.kineticEnergy(), 1e-5);
  // Bottom within the 5% tether slack (measured −0.063 m), median edge strain
  // a few percent (measured 3.8%), all edges shorter than 3× rest (1.8 max).
  EXPECT_GT(summary.lowest, -0.08);
  EXPECT_LT(strainPercentile(cloth, 0.5), 0.06);
  EXPECT_LT(cloth.maxEdgeStrain(), 2.0);
}

TEST(BulletClothLongRun, WavingFlag35KNodes) {
  BulletCloth cloth(flag(186, true));
  const RunSummary summary = run(cloth);
  // Driven steadily: energy oscillates but does not grow (measured flat to 1e-4 J).
  EXPECT_LE(summary.maxEnergySecondHalf, summary.energyMid + 0.02);
  EXPECT_GT(summary.lowest, -0.08);
  EXPECT_LT(strainPercentile(cloth, 0.5), 0.08);
}

TEST(BulletClothLongRun, DrapeOverSphere10KNodes) {
  stain::TriangleMesh mesh = stain::gridMesh(99, 99, 1.0, 1.0);
  mesh.vertexPositions.col(2).setConstant(0.5);
  ClothDef def = describe(mesh);
  const Eigen::Vector3d center(0.5, 0.5, 0.1);
  def.colliders = {ClothCollider::plane(Eigen::Vector3d::Zero(), Eigen::Vector3d::UnitZ()),
                   ClothCollider::sphere(center, 0.25)};
  BulletCloth cloth(def);
  const RunSummary summary = run(cloth);
  EXPECT_LE(summary.maxEnergySecondHalf, summary.energyMid + 1e-3);
  EXPECT_GT(summary.lowest, -0.005);  // m: resting contact sinks ≤ 2 mm (measured)
  double clearance = 1;
  for (int i = 0; i < cloth.vertexCount(); ++i)
    clearance = std::min(clearance, (Eigen::Vector3d(cloth.positions().row(i)) - center).norm() - 0.25);
  EXPECT_GT(clearance, -0.005);
  // Still over the sphere, not slid off: its top rests on it.
  EXPECT_GT(cloth.boundingBox().max().z(), 0.34);
}

}  // namespace
}  // namespace blot::cloth
