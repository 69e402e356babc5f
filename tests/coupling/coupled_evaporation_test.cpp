// The coupling's vapour is the stain's: evaporation alone moves no node. A
// two-way flag swings under gravity with a resting stain whose only process is
// evaporation, including the faster evaporation at the liquid's own edge
// (EvaporationBoundary::WetFront). Every bit of mass a vertex loses leaves as
// vapour with that node's velocity, so the exchange impulse Jᵢ = −Δmᵢ vᵢ − eᵢ vᵢ
// must vanish at every vertex. A coupling that re-derives the evaporation law
// (as it once did, with the mesh-boundary factor only) puts the vapour on the
// wrong nodes at the wet front and pushes them.
#include <blot/coupling/coupled_surface.h>
#include <blot/coupling/liquid_exchange.h>

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>

#include "flag_fixture.h"

namespace blot::coupling {
namespace {

TEST(CoupledEvaporation, EvaporationAloneExertsNoImpulse) {
  for (const stain::EvaporationBoundary boundary :
       {stain::EvaporationBoundary::MeshBoundary, stain::EvaporationBoundary::WetFront}) {
    SCOPED_TRACE(boundary == stain::EvaporationBoundary::WetFront ? "wet front" : "mesh boundary");
    test::CoupledFlag flag = test::makeCoupledFlag(16, true);
    stain::PhysicsSwitches& on = flag.stain.switches;
    on.velocityAdvection = on.densityAdvection = on.densityDiffusion = on.velocityDiffusion = false;
    on.absorption = on.adsorption = on.sources = false;
    flag.stain.liquid.evaporationRate = 0.5;            // kg/(m² s): visible within a few steps
    flag.stain.liquid.boundaryEvaporationFactor = 3.0;  // a_evap
    flag.stain.liquid.evaporationBoundary = boundary;
    auto surface = test::makeCoupledSurface(flag, CouplingMode::TwoWay);
    stain::DropDef drop;
    drop.centerPoint = Eigen::Vector3d(0.5, 0, 0.5);
    drop.radius = 0.2;
    drop.solventMass = 0.05;
    surface->stain().addDrop(drop);

    double worstImpulse = 0, largestVapourMomentum = 0, worstTotal = 0;
    int frontVertices = 0;
    for (int k = 0; k < 40; ++k) {
      const double evaporatedBefore = surface->stain().state().evaporatedSolvent;
      ASSERT_TRUE(surface->step(1.0 / 240).ok());
      const Eigen::VectorXd& e = surface->stain().evaporatedMass();
      const Eigen::MatrixX3d& v = surface->motion().velocities();
      for (int i = 0; i < e.size(); ++i) {
        largestVapourMomentum = std::max(largestVapourMomentum, e[i] * v.row(i).norm());
        worstImpulse = std::max(worstImpulse, surface->pendingImpulses().row(i).norm());
      }
      const double stepTotal = surface->stain().state().evaporatedSolvent - evaporatedBefore;
      worstTotal = std::max(worstTotal, std::abs(e.sum() - stepTotal) / stepTotal);
      if (k == 0) {
        // The liquid's edge evaporates a_evap times faster under WetFront.
        const double inside = e[flag.center()];
        for (int i = 0; i < e.size(); ++i) frontVertices += e[i] > 1.5 * inside;
      }
    }
    std::printf("%s: largest e·|v| %.3g kg m/s, largest |J| %.3g N s, per-vertex sum vs total %.2g, "
                "%d fast-evaporating vertices\n",
                boundary == stain::EvaporationBoundary::WetFront ? "wet front" : "mesh boundary",
                largestVapourMomentum, worstImpulse, worstTotal, frontVertices);
    ASSERT_GT(largestVapourMomentum, 1e-8) << "the test needs evaporation on moving nodes";
    EXPECT_LT(worstImpulse, 1e-9 * largestVapourMomentum);
    EXPECT_LT(worstTotal, 1e-12);
    if (boundary == stain::EvaporationBoundary::WetFront) {
      EXPECT_GT(frontVertices, 0) << "the test needs a wet front that evaporates faster";
    } else {
      EXPECT_EQ(frontVertices, 0) << "the drop does not reach the mesh boundary";
    }
  }
}

TEST(LiquidExchange, ReturnsTheMomentumTheStepMovedAndCountsTheVapour) {
  // Two vertices: 0.2 kg moves from 0 to 1, vertex 1 evaporates 0.05 kg, the
  // free film at 0 loses relative momentum (1, 0, 0) kg m/s.
  Eigen::VectorXd start(2), end(2), vapour(2);
  start << 0.5, 0.1;
  end << 0.3, 0.25;
  vapour << 0.0, 0.05;
  Eigen::MatrixX3d startRelative = Eigen::MatrixX3d::Zero(2, 3), endRelative = Eigen::MatrixX3d::Zero(2, 3);
  startRelative.row(0) << 1, 0, 0;
  Eigen::MatrixX3d v(2, 3), impulses(2, 3);
  v << 1, 2, 0, 0, 0, -3;
  Eigen::Vector3d vapourMomentum = Eigen::Vector3d::Zero();
  EXPECT_EQ(exchangeMomentum(start, end, startRelative, endRelative, v, vapour, impulses, vapourMomentum), -1);
  EXPECT_TRUE(impulses.row(0).isApprox(Eigen::RowVector3d(0.2 * 1 + 1, 0.2 * 2, 0), 1e-15)) << impulses;
  EXPECT_TRUE(impulses.row(1).isApprox(Eigen::RowVector3d(0, 0, 0.15 * 3 + 0.05 * 3), 1e-15)) << impulses;
  EXPECT_TRUE(vapourMomentum.isApprox(Eigen::Vector3d(0, 0, -0.15), 1e-15)) << vapourMomentum;
  end[1] = std::nan("");
  EXPECT_EQ(exchangeMomentum(start, end, startRelative, endRelative, v, vapour, impulses, vapourMomentum), 1);
}

}  // namespace
}  // namespace blot::coupling
