// Evidence for the coupling (docs/coupling.md): a 2,500-vertex flag
// pinned at two corners with a heavy stain sags more in two-way mode than in
// one-way mode, and its liquid trail differs with Coriolis on and off.
// Conservation and rest lengths: coupled_conservation_test.cpp.
#include "bullet_cloth_access.h"
#include <blot/coupling/coupled_surface.h>

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdio>

#include "flag_fixture.h"

namespace blot::coupling {
namespace {

constexpr double kFrame = 1.0 / 60;

// Mass-weighted centroid (m) of the liquid on the surface now.
Eigen::Vector3d liquidCentroid(const CoupledSurface& s) {
  const Eigen::VectorXd& m = s.liquidNodeMasses();
  return (s.motion().positions().transpose() * m) / m.sum();
}

struct FlagRun {
  double lowest = 0;               // lowest z of the cloth (m)
  Eigen::Vector3d clothCentroid;   // mean node position (m)
  Eigen::Vector3d liquidCentroid;  // liquid centroid (m)
  double worstStrain = 0;          // largest mesh-edge strain |ℓ/ℓ̄ − 1| seen after the stain (1)
  bool healthy = false;
};

// A 2,500-vertex flag hanging from two corners, settled for 0.5 s, then a heavy
// stain (0.3 kg solvent, twice the cloth's 0.15 kg) at the centre, then
// `frames` more frames. waving: both pins swing ±10 cm across the flag at 1 Hz.
// absorptionRate (1/s): how fast the stain soaks into the fibres.
FlagRun runFlag(CouplingMode mode, bool coriolis, bool waving, double absorptionRate, int frames) {
  test::CoupledFlag flag = test::makeCoupledFlag(49, true);
  flag.stain.liquid.absorptionRate = absorptionRate;
  if (waving)
    for (cloth::ClothPin& pin : flag.cloth.pins) {
      pin.motion.amplitude = Eigen::Vector3d(0, 0.1, 0);
      pin.motion.frequency = 1.0;
    }
  flag.stain.switches.coriolis = coriolis;
  flag.stain.strainTolerance = 0.02;
  auto surface = test::makeCoupledSurface(flag, mode);
  for (int k = 0; k < 30; ++k) EXPECT_EQ(surface->step(kFrame).status, stain::StepStatus::Ok);
  surface->stain().addDrop(test::heavyCentreDrop(flag));
  FlagRun r;
  for (int k = 0; k < frames; ++k) {
    EXPECT_EQ(surface->step(kFrame).status, stain::StepStatus::Ok) << "frame " << k;
    r.worstStrain = std::max(r.worstStrain, blot::testing::bulletClothOf(*surface).maxEdgeStrain());
  }
  const Eigen::MatrixX3d& x = surface->motion().positions();
  r.lowest = x.col(2).minCoeff();
  r.clothCentroid = x.colwise().mean().transpose();
  r.liquidCentroid = liquidCentroid(*surface);
  r.healthy = blot::testing::bulletClothOf(*surface).isHealthy();
  return r;
}

// The stain runs down the flag (default absorption, K_p = 0.1/s) and collects
// at the hem; in two-way mode the flag carries its weight, and the cloth stays
// cloth (no edge crushed or stretched by half: the corner-pin edges alone
// reach ~15 % with or without liquid).
TEST(CoupledFlag, TwoWaySagsMoreThanOneWay) {
  const FlagRun oneWay = runFlag(CouplingMode::OneWay, true, false, 0.1, 60);
  const FlagRun twoWay = runFlag(CouplingMode::TwoWay, true, false, 0.1, 60);
  ASSERT_TRUE(oneWay.healthy && twoWay.healthy);
  const double lowestDrop = oneWay.lowest - twoWay.lowest;
  const double centroidDrop = oneWay.clothCentroid.z() - twoWay.clothCentroid.z();
  std::printf("two-way vs one-way 1 s after the stain: lowest point %.2f mm lower, cloth centroid %.2f mm lower; "
              "largest edge strain %.3f (one-way %.3f)\n",
              1e3 * lowestDrop, 1e3 * centroidDrop, twoWay.worstStrain, oneWay.worstStrain);
  // The liquid's weight (twice the cloth's) stretches the flag within the
  // tethers' 5% slack: millimetres, not micrometres.
  EXPECT_GT(lowestDrop, 1e-3);
  EXPECT_GT(centroidDrop, 1e-3);
  EXPECT_LT(twoWay.worstStrain, 0.5);
}

// Paper Fig. 10: on a waving flag the Coriolis force bends the trail of the
// liquid that has not soaked in yet (K_p = 1/s).
TEST(CoupledFlag, CoriolisChangesTheLiquidTrailOnAWavingFlag) {
  const FlagRun on = runFlag(CouplingMode::TwoWay, true, true, 1.0, 60);
  const FlagRun off = runFlag(CouplingMode::TwoWay, false, true, 1.0, 60);
  ASSERT_TRUE(on.healthy && off.healthy);
  const double shift = (on.liquidCentroid - off.liquidCentroid).norm();
  std::printf("waving flag, 1 s after the stain: liquid centroid with vs without Coriolis differs by %.3f mm "
              "(x %.3f, y %.3f, z %.3f mm)\n",
              1e3 * shift, 1e3 * (on.liquidCentroid.x() - off.liquidCentroid.x()),
              1e3 * (on.liquidCentroid.y() - off.liquidCentroid.y()),
              1e3 * (on.liquidCentroid.z() - off.liquidCentroid.z()));
  EXPECT_GT(shift, 1e-4);
}

}  // namespace
}  // namespace blot::coupling
