// Which terms the stain step runs ("model no more than a scene
// needs ... each scene reports which terms ran"): a dry step runs no
// transport, switched-off and zero-coefficient terms are skipped and reported
// as not run, diffusion reports its method and rows, and skipping a term with
// a zero coefficient leaves the results bit-identical.
#include <blot/stain/stages/interaction.h>
#include <blot/stain/geometry/mesh_primitives.h>
#include <blot/stain/stain_solver.h>

#include <gtest/gtest.h>

#include <cmath>
#include <string>

namespace blot::stain {
namespace {

constexpr unsigned kTransportTerms =
    static_cast<unsigned>(StepTerm::Gravity) | static_cast<unsigned>(StepTerm::LinearInertia) |
    static_cast<unsigned>(StepTerm::Coriolis) | static_cast<unsigned>(StepTerm::FilmPressure) |
    static_cast<unsigned>(StepTerm::VelocityAdvection) | static_cast<unsigned>(StepTerm::DensityAdvection) |
    static_cast<unsigned>(StepTerm::DensityDiffusionKrylov) | static_cast<unsigned>(StepTerm::DensityDiffusionDirect) |
    static_cast<unsigned>(StepTerm::VelocityDiffusionKrylov) |
    static_cast<unsigned>(StepTerm::VelocityDiffusionDirect) | static_cast<unsigned>(StepTerm::Absorption) |
    static_cast<unsigned>(StepTerm::Adsorption) | static_cast<unsigned>(StepTerm::Evaporation);

/// A 0.6 m square grid (31 x 31 vertices) centred at the origin in z = 0.
struct Cloth {
  TriangleMesh mesh;
  SurfaceTopology topology;
  explicit Cloth(int cells = 30)
      : mesh([cells] {
          TriangleMesh m = gridMesh(cells, cells, 0.6, 0.6);
          m.vertexPositions.col(0).array() -= 0.3;
          m.vertexPositions.col(1).array() -= 0.3;
          return m;
        }()),
        topology(mesh.faces, static_cast<int>(mesh.vertexPositions.rows())) {}
  int vertexCount() const { return topology.vertexCount(); }
  FabricField fabric(double diffusivity = 1e-4) const {
    return isotropicFabricField(topology.faceCount(), diffusivity, 1e-4);
  }
  /// Positions turned by `angle` about a tilted axis (a rigid motion that
  /// gives gravity a tangential part), and its rotation matrix.
  Matrix3 rotation(double angle) const {
    return Eigen::AngleAxisd(angle, Vector3(0.3, 0.1, 1.0).normalized()).toRotationMatrix();
  }
  RowVectors3 turned(double angle) const { return mesh.vertexPositions * rotation(angle).transpose(); }
};

DropDef smallDrop() {
  DropDef drop;
  drop.centerPoint = Vector3(0.05, 0.0, 0.0);
  drop.radius = 0.06;
  drop.solventMass = 2e-3;
  drop.soluteMass = 4e-4;
  return drop;
}

TEST(StepTerms, DryStepRunsNoTransportTerms) {
  const Cloth cloth;
  StainSolver solver(cloth.topology, cloth.mesh.vertexPositions, cloth.fabric(), StainSolverDef());
  // A dry, static surface: the first step assembles the diffusion systems
  // (no solve: nothing is factorized), later ones run nothing.
  ASSERT_EQ(solver.step(0.01, cloth.mesh.vertexPositions).status, StepStatus::Ok);
  EXPECT_EQ(solver.profile().terms, static_cast<unsigned>(StepTerm::SystemAssembly));
  EXPECT_EQ(solver.profile().factorizations, 0);
  ASSERT_EQ(solver.step(0.01, cloth.mesh.vertexPositions).status, StepStatus::Ok);
  EXPECT_EQ(solver.profile().terms, 0u) << describeTerms(solver.profile());
  EXPECT_EQ(solver.profile().wetVertices, 0);
  EXPECT_EQ(solver.profile().haloVertices, 0);
  EXPECT_EQ(solver.profile().geometryVertices, 0);
  EXPECT_EQ(describeTerms(solver.profile()), "none (wet 0 + halo 0 of " + std::to_string(cloth.vertexCount()) + ")");

  // A dry, moving surface: only the geometry refresh, and no vertex's
  // per-vertex geometry (there is no band to compute it on).
  for (int k = 1; k <= 3; ++k) {
    ASSERT_EQ(solver.stepRigid(0.01, cloth.turned(0.02 * k), cloth.rotation(0.02 * k)).status, StepStatus::Ok);
    EXPECT_EQ(solver.profile().terms, static_cast<unsigned>(StepTerm::RigidFrames)) << describeTerms(solver.profile());
    EXPECT_EQ(solver.profile().geometryVertices, 0);
    EXPECT_EQ(solver.profile().terms & kTransportTerms, 0u);
  }
  ASSERT_EQ(solver.step(0.01, cloth.turned(0.08)).status, StepStatus::Ok);
  EXPECT_TRUE(solver.profile().ran(StepTerm::RotationFits));
  EXPECT_EQ(solver.profile().geometryVertices, 0);
  EXPECT_EQ(solver.geometry().rotationFitStats().fittedVertices, 0);
  EXPECT_EQ(solver.profile().terms & kTransportTerms, 0u);
  // Nothing moved the (zero) state.
  EXPECT_EQ(solver.state().solvent.cwiseAbs().maxCoeff(), 0.0);
  EXPECT_EQ(solver.state().velocities.cwiseAbs().maxCoeff(), 0.0);
}

TEST(StepTerms, WetStepOnAMovingSurfaceRunsEveryTermOnTheWetRegionOnly) {
  const Cloth cloth;
  StainSolverDef def;
  def.switches.filmPressure = true;
  StainSolver solver(cloth.topology, cloth.mesh.vertexPositions, cloth.fabric(), def);
  solver.addDrop(smallDrop());
  for (int k = 1; k <= 3; ++k)
    ASSERT_EQ(solver.stepRigid(0.01, cloth.turned(0.02 * k), cloth.rotation(0.02 * k)).status, StepStatus::Ok);
  const StepProfile& p = solver.profile();
  for (const StepTerm term : {StepTerm::RigidFrames, StepTerm::Gravity, StepTerm::LinearInertia, StepTerm::Coriolis,
                              StepTerm::FilmPressure, StepTerm::VelocityAdvection, StepTerm::DensityAdvection,
                              StepTerm::Absorption, StepTerm::Adsorption, StepTerm::Evaporation})
    EXPECT_TRUE(p.ran(term)) << stepTermName(term) << " did not run: " << describeTerms(p);
  EXPECT_FALSE(p.ran(StepTerm::Sources));
  EXPECT_FALSE(p.ran(StepTerm::IntrinsicRebuild)) << "a rigid motion keeps the metric";
  EXPECT_FALSE(p.ran(StepTerm::SystemAssembly)) << "same h and metric: the systems are kept";
  EXPECT_FALSE(p.ran(StepTerm::Factorization));

  // The wet, soaked and halo counts are those of the state at the start of
  // the step: recount from the state before one more step. Wet: free liquid
  // above the threshold; soaked: only fibre-held liquid above it (filed
  // apart, u = 0); halo: the ring around the wet set, soaked ones included.
  const StainState before = solver.state();
  const double threshold = def.liquid.wetThreshold;
  const int n = cloth.vertexCount();
  std::vector<char> mask(static_cast<size_t>(n), 0);
  int wet = 0, halo = 0, soaked = 0;
  for (int i = 0; i < n; ++i) {
    if (!(before.solvent[i] > threshold || before.absorbedSolvent[i] > threshold || before.solute[i] > threshold))
      continue;
    if (!(before.solvent[i] + before.solute[i] > threshold) && before.absorbedSolvent[i] > threshold) {
      ++soaked;
      continue;
    }
    mask[static_cast<size_t>(i)] = 2;
    ++wet;
  }
  for (int i = 0; i < n; ++i) {
    if (mask[static_cast<size_t>(i)] != 2) continue;
    for (int m = cloth.topology.ringOffsets()[static_cast<size_t>(i)];
         m < cloth.topology.ringOffsets()[static_cast<size_t>(i) + 1]; ++m) {
      char& w = mask[static_cast<size_t>(cloth.topology.ringNeighbors()[static_cast<size_t>(m)])];
      if (w == 0) {
        w = 1;
        ++halo;
      }
    }
  }
  ASSERT_EQ(solver.stepRigid(0.01, cloth.turned(0.08), cloth.rotation(0.08)).status, StepStatus::Ok);
  const StepProfile& q = solver.profile();
  EXPECT_EQ(q.wetVertices, wet);
  EXPECT_EQ(q.haloVertices, halo);
  EXPECT_EQ(q.soakedVertices, soaked);
  EXPECT_GT(wet, 0);
  EXPECT_GT(soaked, 0) << "the drop's centre should have soaked in by now";
  EXPECT_LT(wet + halo, n / 4) << "a small drop wets a small part of the cloth";
  // Diffusion at this stiffness runs by CG on the liquid's Krylov support, not on every vertex.
  ASSERT_TRUE(q.ran(StepTerm::DensityDiffusionKrylov)) << describeTerms(q);
  EXPECT_FALSE(q.ran(StepTerm::DensityDiffusionDirect));
  EXPECT_GE(q.densityDiffusionVertices, wet);
  EXPECT_LT(q.densityDiffusionVertices, n / 2);
  ASSERT_TRUE(q.ran(StepTerm::VelocityDiffusionKrylov)) << describeTerms(q);
  // The velocity solve covers the liquid band less the vertices with a
  // neighbour outside it (their extended values are the boundary data).
  const LiquidBand& band = solver.band();
  ASSERT_GE(band.rings, 2);
  EXPECT_EQ(q.bandVertices, band.size());
  int interior = 0;
  for (const int v : band.vertices) {
    bool inside = true;
    for (int m = cloth.topology.ringOffsets()[static_cast<size_t>(v)];
         m < cloth.topology.ringOffsets()[static_cast<size_t>(v) + 1]; ++m) {
      inside = inside && band.levels[static_cast<size_t>(cloth.topology.ringNeighbors()[static_cast<size_t>(m)])] >= 0;
    }
    interior += inside ? 1 : 0;
  }
  EXPECT_GT(interior, wet);
  EXPECT_LT(interior, band.size());
  EXPECT_EQ(q.velocityDiffusionVertices, interior)
      << "the velocity solve covers the band less the vertices next to its outside";
  EXPECT_LT(q.bandVertices, n / 2);
  EXPECT_GE(q.advectionVertices, wet + halo);
  EXPECT_LT(q.advectionVertices, n / 2);
  const std::string text = describeTerms(q);
  EXPECT_NE(text.find("density-diffusion-krylov[" + std::to_string(q.densityDiffusionVertices) + "]"),
            std::string::npos)
      << text;
  EXPECT_NE(text.find("(wet " + std::to_string(wet) + " + halo " + std::to_string(halo) + ", soaked " +
                      std::to_string(soaked) + " of " + std::to_string(n) + ")"),
            std::string::npos)
      << text;
}

TEST(StepTerms, StiffDiffusionReportsTheDirectSolveOnEveryVertex) {
  const Cloth cloth;
  // h L_ii / A_i ≈ 4 h D / dx² = 4 · 0.01 · 0.5 / 0.02² = 50: far above the CG threshold.
  StainSolver solver(cloth.topology, cloth.mesh.vertexPositions, cloth.fabric(0.5), StainSolverDef());
  solver.addDrop(smallDrop());
  ASSERT_EQ(solver.step(0.01, cloth.mesh.vertexPositions).status, StepStatus::Ok);
  const StepProfile& p = solver.profile();
  ASSERT_TRUE(p.ran(StepTerm::DensityDiffusionDirect)) << describeTerms(p);
  EXPECT_FALSE(p.ran(StepTerm::DensityDiffusionKrylov));
  EXPECT_EQ(p.densityDiffusionVertices, cloth.vertexCount());
  // A static surface: no inertia, no Coriolis, no geometry refresh.
  EXPECT_FALSE(p.ran(StepTerm::LinearInertia));
  EXPECT_FALSE(p.ran(StepTerm::Coriolis));
  EXPECT_FALSE(p.ran(StepTerm::RigidFrames));
  EXPECT_FALSE(p.ran(StepTerm::RotationFits));
  EXPECT_TRUE(p.ran(StepTerm::Gravity));
}

TEST(StepTerms, SwitchedOffAndZeroCoefficientTermsAreNotRun) {
  const Cloth cloth;
  struct Case {
    const char* name;
    void (*configure)(StainSolverDef&);
    StepTerm skipped;
  };
  const Case cases[] = {
      {"absorption switched off", [](StainSolverDef& d) { d.switches.absorption = false; }, StepTerm::Absorption},
      {"absorption rate 0", [](StainSolverDef& d) { d.liquid.absorptionRate = 0; }, StepTerm::Absorption},
      {"adsorption switched off", [](StainSolverDef& d) { d.switches.adsorption = false; }, StepTerm::Adsorption},
      {"desorption rate 0", [](StainSolverDef& d) { d.liquid.desorptionRate = 0; }, StepTerm::Adsorption},
      {"evaporation switched off", [](StainSolverDef& d) { d.switches.evaporation = false; }, StepTerm::Evaporation},
      {"evaporation rate 0", [](StainSolverDef& d) { d.liquid.evaporationRate = 0; }, StepTerm::Evaporation},
      {"zero gravity", [](StainSolverDef& d) { d.gravity.setZero(); }, StepTerm::Gravity},
      {"gravity switched off", [](StainSolverDef& d) { d.switches.gravity = false; }, StepTerm::Gravity},
      {"coriolis switched off", [](StainSolverDef& d) { d.switches.coriolis = false; }, StepTerm::Coriolis},
      {"velocity advection off", [](StainSolverDef& d) { d.switches.velocityAdvection = false; },
       StepTerm::VelocityAdvection},
      {"density advection off", [](StainSolverDef& d) { d.switches.densityAdvection = false; },
       StepTerm::DensityAdvection},
      {"film pressure without gravity",
       [](StainSolverDef& d) {
         d.switches.filmPressure = true;
         d.gravity.setZero();
       },
       StepTerm::FilmPressure},
  };
  for (const Case& c : cases) {
    StainSolverDef def;
    c.configure(def);
    StainSolver solver(cloth.topology, cloth.mesh.vertexPositions, cloth.fabric(), def);
    solver.addDrop(smallDrop());
    unsigned ranOnce = 0;
    for (int k = 1; k <= 3; ++k) {
      ASSERT_EQ(solver.stepRigid(0.01, cloth.turned(0.02 * k), cloth.rotation(0.02 * k)).status, StepStatus::Ok)
          << c.name;
      ranOnce |= solver.profile().terms;
    }
    EXPECT_EQ(ranOnce & static_cast<unsigned>(c.skipped), 0u) << c.name << ": " << describeTerms(solver.profile());
    EXPECT_TRUE(solver.profile().ran(StepTerm::VelocityDiffusionKrylov)) << c.name << ": the rest still runs";
    if (c.skipped == StepTerm::Absorption) {
      EXPECT_EQ(solver.state().absorbedSolvent.cwiseAbs().maxCoeff(), 0.0) << c.name << ": nothing absorbed";
    }
  }
}

TEST(StepTerms, DiffusionSwitchedOffIsNotRun) {
  const Cloth cloth;
  StainSolverDef def;
  def.switches.densityDiffusion = false;
  StainSolver solver(cloth.topology, cloth.mesh.vertexPositions, cloth.fabric(), def);
  solver.addDrop(smallDrop());
  // Moving, so that tangential gravity gives the liquid a velocity to diffuse.
  for (int k = 1; k <= 2; ++k)
    ASSERT_EQ(solver.stepRigid(0.01, cloth.turned(0.02 * k), cloth.rotation(0.02 * k)).status, StepStatus::Ok);
  EXPECT_FALSE(solver.profile().ran(StepTerm::DensityDiffusionKrylov));
  EXPECT_FALSE(solver.profile().ran(StepTerm::DensityDiffusionDirect));
  EXPECT_EQ(solver.profile().densityDiffusionVertices, 0);
  EXPECT_TRUE(solver.profile().ran(StepTerm::VelocityDiffusionKrylov) ||
              solver.profile().ran(StepTerm::VelocityDiffusionDirect));
}

TEST(StepTerms, HeldRegionOnADryClothRunsSources) {
  const Cloth cloth;
  StainSolver solver(cloth.topology, cloth.mesh.vertexPositions, cloth.fabric(), StainSolverDef());
  HeldRegion region;
  region.vertices = {cloth.vertexCount() / 2};
  region.solventDensity = 0.5;
  solver.addHeldRegion(region);
  // Held regions are topped up before the forces: the liquid they
  // add is wet in the same step and transported with it.
  ASSERT_EQ(solver.step(0.01, cloth.mesh.vertexPositions).status, StepStatus::Ok);
  EXPECT_TRUE(solver.profile().ran(StepTerm::Sources));
  EXPECT_EQ(solver.profile().wetVertices, 1);
  EXPECT_NE(solver.profile().terms & kTransportTerms, 0u) << "the held liquid is transported in its first step";
  EXPECT_TRUE(solver.profile().ran(StepTerm::Absorption));
}

// Skipping a zero-rate term is exact: the interaction stage with a rate of
// zero and its switch on gives bit-identically the state it gives with the
// switch off (so the solver may skip it and report it as not run).
TEST(StepTerms, ZeroRateTermsChangeNothingWhenRun) {
  const Cloth cloth;
  StainSolver reference(cloth.topology, cloth.mesh.vertexPositions, cloth.fabric(), StainSolverDef());
  reference.addDrop(smallDrop());
  for (int k = 1; k <= 20; ++k) ASSERT_EQ(reference.step(0.01, cloth.mesh.vertexPositions).status, StepStatus::Ok);
  const StainState start = reference.state();
  ASSERT_GT(start.absorbedSolvent.maxCoeff(), 0.0);
  const auto run = [&](bool absorption, bool adsorption, bool evaporation, const LiquidParameters& liquid) {
    PhysicsSwitches on;
    on.absorption = absorption;
    on.adsorption = adsorption;
    on.evaporation = evaporation;
    const StepContext ctx = makeStepContext(0.01, Vector3(0, 0, -9.8), on, liquid);
    StainState s = start;
    interact(ctx, cloth.topology, reference.geometry().intrinsic(), std::vector<char>(), s);
    return s;
  };
  const auto same = [](const StainState& a, const StainState& b) {
    return a.solvent == b.solvent && a.solute == b.solute && a.absorbedSolvent == b.absorbedSolvent &&
           a.absorbedSolute == b.absorbedSolute && a.adsorbedSolute == b.adsorbedSolute &&
           a.evaporatedSolvent == b.evaporatedSolvent;
  };
  LiquidParameters liquid;
  liquid.absorptionRate = 0;
  EXPECT_TRUE(same(run(true, true, true, liquid), run(false, true, true, liquid))) << "K_p = 0";
  liquid = LiquidParameters();
  liquid.desorptionRate = 0;
  EXPECT_TRUE(same(run(true, true, true, liquid), run(true, false, true, liquid))) << "K_d = 0";
  liquid = LiquidParameters();
  liquid.evaporationRate = 0;
  EXPECT_TRUE(same(run(true, true, true, liquid), run(true, true, false, liquid))) << "K_evap = 0";
  // And the stage does change the state when a rate is not zero (the
  // comparison above can fail).
  EXPECT_FALSE(same(run(true, true, true, LiquidParameters()), run(false, true, true, LiquidParameters())));
}

// The backup is taken lazily (before the first change); a step that fails
// validation still leaves the state as it found it, wet or dry.
TEST(StepTerms, FailedStepLeavesTheStateAsItWasWetOrDry) {
  const Cloth cloth;
  const int far = 0;  // a corner, far from the drop
  for (const bool wet : {false, true}) {
    StainSolver solver(cloth.topology, cloth.mesh.vertexPositions, cloth.fabric(), StainSolverDef());
    if (wet) solver.addDrop(smallDrop());
    ASSERT_EQ(solver.step(0.01, cloth.mesh.vertexPositions).status, StepStatus::Ok);
    // A NaN deposit at a dry vertex: not liquid, so it does not make the step wet.
    solver.mutableState().adsorbedSolute[far] = std::nan("");
    const StainState before = solver.state();
    const StepReport r = solver.stepRigid(0.01, cloth.turned(0.02), cloth.rotation(0.02));
    EXPECT_EQ(r.status, StepStatus::NonFinite) << (wet ? "wet" : "dry");
    EXPECT_EQ(r.vertex, far);
    EXPECT_EQ(solver.profile().wetVertices > 0, wet);
    EXPECT_EQ(solver.stepCount(), 1);
    const StainState& after = solver.state();
    EXPECT_TRUE(after.solvent == before.solvent && after.solute == before.solute &&
                after.absorbedSolvent == before.absorbedSolvent && after.absorbedSolute == before.absorbedSolute &&
                after.velocities == before.velocities)
        << (wet ? "wet" : "dry") << ": the state must be restored";
    EXPECT_TRUE(std::isnan(after.adsorbedSolute[far]));
  }
}

// Once a stain has dried (deposits only), steps change nothing and run nothing.
TEST(StepTerms, DriedStainRunsNothingAndKeepsItsDeposit) {
  const Cloth cloth;
  StainSolverDef def;
  def.liquid.evaporationRate = 50.0;  // dries within a few steps
  StainSolver solver(cloth.topology, cloth.mesh.vertexPositions, cloth.fabric(), def);
  solver.addDrop(smallDrop());
  int steps = 0;
  do {
    ASSERT_EQ(solver.step(0.01, cloth.mesh.vertexPositions).status, StepStatus::Ok);
  } while (solver.profile().wetVertices > 0 && ++steps < 50);
  ASSERT_EQ(solver.profile().wetVertices, 0) << "the stain should have dried";
  ASSERT_GT(solver.state().adsorbedSolute.maxCoeff(), 0.0);
  const StainState dried = solver.state();
  for (int k = 0; k < 3; ++k) {
    ASSERT_EQ(solver.step(0.01, cloth.mesh.vertexPositions).status, StepStatus::Ok);
    EXPECT_EQ(solver.profile().terms, 0u) << describeTerms(solver.profile());
  }
  EXPECT_TRUE(solver.state().adsorbedSolute == dried.adsorbedSolute);
  EXPECT_TRUE(solver.state().velocities == dried.velocities);
  EXPECT_LT(solver.massBudget().soluteError(), 1e-12);
}

TEST(StepTerms, NamesAreDistinct) {
  for (int a = 0; a < kStepTermCount; ++a)
    for (int b = a + 1; b < kStepTermCount; ++b)
      EXPECT_STRNE(stepTermName(static_cast<StepTerm>(1u << a)), stepTermName(static_cast<StepTerm>(1u << b)));
}

}  // namespace
}  // namespace blot::stain
