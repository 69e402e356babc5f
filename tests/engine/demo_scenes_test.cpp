// Short versions of the paper-figure scenes in assets/scenes/ (docs/gallery.md):
// each loads the shipped file, shrinks it (smaller mesh, fewer steps) through
// the same JSON the user edits, and checks a number the picture shows.
//
// Design note: overriding keys in the parsed JSON (rather than building
// EngineDefs by hand) keeps the test on the exact scene a user runs, so a
// scene edit that breaks its figure's point fails here. Tolerances are stated
// per test; none is timed.
#include <blot/engine/engine.h>
#include <blot/engine/scene.h>

#include <gtest/gtest.h>
#include <nlohmann/json.hpp>

#include <Eigen/Geometry>

#include <cmath>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <memory>
#include <sstream>
#include <string>
#include <tuple>

namespace blot::engine {
namespace {

const std::string kScenes = std::string(BLOT_ASSETS_DIR) + "/scenes/";

nlohmann::json readScene(const std::string& file) {
  std::ifstream in(kScenes + file);
  EXPECT_TRUE(in) << kScenes + file;
  std::stringstream text;
  text << in.rdbuf();
  return nlohmann::json::parse(text.str());
}

SceneDef parse(const nlohmann::json& j, const std::string& file) { return parseScene(j.dump(), file, kScenes); }

/// Area-weighted centre (m, world) of `weight` (kg/m²) on the current shape.
Eigen::Vector3d centre(const Engine& e, const Eigen::VectorXd& weight) {
  const Eigen::MatrixX3d& x = e.positions();
  Eigen::VectorXd area = Eigen::VectorXd::Zero(x.rows());
  for (Eigen::Index t = 0; t < e.faces().rows(); ++t) {
    const auto f = e.faces().row(t);
    const double a = 0.5 * (x.row(f(1)) - x.row(f(0))).cross(x.row(f(2)) - x.row(f(0))).norm();
    for (int k = 0; k < 3; ++k) area[f(k)] += a / 3.0;
  }
  const Eigen::VectorXd m = area.cwiseProduct(weight.cwiseMax(0.0));
  return x.transpose() * m / m.sum();
}

Eigen::VectorXd totalSolute(const Engine& e) { return e.solute() + e.absorbedSolute() + e.adsorbedSolute(); }

// Figs. 1, 9: on the rotating bunny (here a small square with the same
// fabric, motion and source) the held source keeps adding wine, so the added mass and
// the stained area grow from frame to frame while the budget stays closed.
TEST(DemoScenes, RotatingBunnyStainGrowsWhileTheSourceIsOn) {
  for (const char* file : {"rotating_bunny.json", "rotating_bunny_weft_z.json"}) {
    nlohmann::json j = readScene(file);
    // A flat square in the xz plane keeps both wefts (x and z) tangent
    // everywhere; on a small sphere a held weft is normal at two poles.
    j["mesh"] = {{"patch", {{"size", {0.6, 0.6}}, {"resolution", {16, 16}}, {"plane", "xz"}}}};
    j["drops"][0]["point"] = {0.1, 0.0, 0.1};
    j["held_regions"][0]["center"] = {0.1, 0.0, 0.1};
    j["held_regions"][0]["radius"] = 0.08;
    Engine e(engineDef(parse(j, file)));
    double added = e.statistics().massBudget.addedSolute;
    // Stained: more than 5 % of the held spot's solute density.
    const double stainedDensity = 0.05 * j["held_regions"][0]["solute_density"].get<double>();
    long stained = 0;
    for (int frame = 0; frame < 4; ++frame) {
      ASSERT_EQ(e.advanceSteps(5).status, stain::StepStatus::Ok) << file;
      const stain::MassBudget b = e.statistics().massBudget;
      EXPECT_GT(b.addedSolute, added * (1 + 1e-6)) << file << " frame " << frame;
      added = b.addedSolute;
      const long now = (totalSolute(e).array() > stainedDensity).count();
      EXPECT_GE(now, stained) << file << " frame " << frame;
      stained = now;
      EXPECT_LT(std::abs(b.soluteError()), 1e-9) << file;
    }
    EXPECT_GT(stained, 5) << file;
  }
}

// Fig. 9 (a, c): the same bunny scenes with one drop and no source add
// nothing after the drop (the growth above is the source's).
TEST(DemoScenes, RotatingBunnyWithoutSourceAddsNothing) {
  for (const char* file : {"rotating_bunny_no_source.json", "rotating_bunny_weft_z_no_source.json"}) {
    nlohmann::json j = readScene(file);
    EXPECT_FALSE(j.contains("held_regions")) << file;
    j["mesh"] = {{"patch", {{"size", {0.6, 0.6}}, {"resolution", {16, 16}}, {"plane", "xz"}}}};
    j["drops"][0]["point"] = {0.1, 0.0, 0.1};
    const EngineDef def = engineDef(parse(j, file));
    ASSERT_EQ(def.drops.size(), 1u) << file;
    Engine e(def);
    ASSERT_EQ(e.advanceSteps(1).status, stain::StepStatus::Ok) << file;
    const double added = e.statistics().massBudget.addedSolute;
    EXPECT_NEAR(added, def.drops[0].drop.soluteMass, 1e-12) << file;
    ASSERT_EQ(e.advanceSteps(10).status, stain::StepStatus::Ok) << file;
    EXPECT_EQ(e.statistics().massBudget.addedSolute, added) << file;
  }
}

// Fig. 6: four equal drops with different random splash velocities on a still,
// hanging flag. The drops of each pair (upper, lower) sit exactly 24 grid
// columns apart, so without the splash their stains would be translates of
// each other; the splash must make them differ (relative L1 > 1%).
TEST(DemoScenes, StaticFlagSplashesDiffer) {
  nlohmann::json j = readScene("static_flag_splash.json");
  Engine e(engineDef(parse(j, "static_flag_splash.json")));
  ASSERT_EQ(e.advanceSteps(40).status, stain::StepStatus::Ok);
  const Eigen::VectorXd s = totalSolute(e);
  const int n = 51;  // vertices per row
  double difference = 0, total = 0;
  for (int row = n / 2 + 1; row < n; ++row) {  // upper half
    for (int i = 0; i + 24 < n && i < 25; ++i) {
      const double a = s[row * n + i], b = s[row * n + i + 24];
      difference += std::abs(a - b);
      total += a;
    }
  }
  EXPECT_GT(difference, 0.01 * total);
  // The lower pair too (same 24-column shift, rows below the middle).
  double lowerDifference = 0, lowerTotal = 0;
  for (int row = 0; row < n / 2; ++row) {  // lower half
    for (int i = 0; i < 25 && i + 24 < n; ++i) {
      lowerDifference += std::abs(s[row * n + i] - s[row * n + i + 24]);
      lowerTotal += s[row * n + i];
    }
  }
  EXPECT_GT(lowerDifference, 0.01 * lowerTotal);
  std::printf("  splash: relative L1 difference upper %.3f, lower %.3f\n", difference / total, lowerDifference / lowerTotal);
  EXPECT_LT(std::abs(e.statistics().massBudget.soluteError()), 1e-9);
}

// Figs. 7, 10: the two-way flag carries the liquid's weight, so it hangs lower
// than the one-way flag under the same pins, wind and drop; switching the
// Coriolis force off changes the stain.
TEST(DemoScenes, TwoWayFlagSagsMoreThanOneWayAndCoriolisMatters) {
  const auto run = [](const char* file) {
    nlohmann::json j = readScene(file);
    j["mesh"]["patch"]["resolution"] = {20, 20};
    const SceneDef scene = parse(j, file);
    EXPECT_TRUE(scene.outputs.preview.restShape) << file;
    auto e = std::make_unique<Engine>(engineDef(scene));
    EXPECT_EQ(e->advanceSteps(60).status, stain::StepStatus::Ok) << file;
    return e;
  };
  const auto oneWay = run("waving_flag.json");
  const auto twoWay = run("waving_flag_two_way.json");
  const auto noCoriolis = run("waving_flag_two_way_no_coriolis.json");
  const double zOne = oneWay->positions().col(2).mean(), zTwo = twoWay->positions().col(2).mean();
  std::printf("  flag mean height: one-way %.4f m, two-way %.4f m\n", zOne, zTwo);
  EXPECT_LT(zTwo, zOne - 1e-3) << "one-way mean height " << zOne << " m, two-way " << zTwo << " m";
  const double change = (totalSolute(*twoWay) - totalSolute(*noCoriolis)).lpNorm<1>();
  EXPECT_GT(change, 1e-4 * totalSolute(*twoWay).lpNorm<1>());
}

// Fig. 8: the dropped tablecloth drapes over the 0.75 m table (its corners end
// below the top, its centre rests on it) and the wine near the edge is
// carried down the falling flap, with and without the Coriolis force.
TEST(DemoScenes, TableclothDrapesAndCarriesTheStainDown) {
  for (const char* file : {"tablecloth.json", "tablecloth_no_coriolis.json"}) {
    nlohmann::json j = readScene(file);
    j["mesh"]["patch"]["resolution"] = {24, 24};
    Engine e(engineDef(parse(j, file)));
    const double z0 = centre(e, e.solvent() + e.absorbedSolvent()).z();
    ASSERT_EQ(e.advanceSteps(90).status, stain::StepStatus::Ok) << file;
    const Eigen::MatrixX3d& x = e.positions();
    EXPECT_LT(x(0, 2), 0.7) << file << ": corner height";
    const int middle = 12 * 25 + 12;
    EXPECT_NEAR(x(middle, 2), 0.75, 0.05) << file << ": centre height";
    EXPECT_LT(centre(e, totalSolute(e)).z(), z0 - 0.02) << file;
  }
}

// Fig. 5: the rotating disc with no inertial forces / translational only /
// full. With the liquid starting at rest on the cloth, its inertial-frame
// centre should follow a free particle's straight line: full inertia misses
// it by less than a third of either partial model's miss (at 0.3 s on this
// 16-ring disc: translational only 0.043 m, none 0.059 m, full 0.007 m; the
// shipped 30-ring scene is similar). In the cloth's own (rotating) frame the
// Coriolis force turns the outward trail to the right for counter-clockwise
// rotation: the full run's displacement is clockwise of the translation-only one.
TEST(DemoScenes, RotatingRegionFollowsTheFreeParticleAndCoriolisTurnsRight) {
  nlohmann::json j = readScene("rotating_region.json");
  j["mesh"]["disc"]["rings"] = 16;
  const SceneDef scene = parse(j, "rotating_region.json");
  const int steps = 60;
  struct Result {
    double miss;
    Eigen::Vector3d material;  // displacement in the cloth frame (m)
  };
  const auto run = [&](bool linear, bool coriolis) {
    EngineDef def = engineDef(scene);
    def.stain.switches.linearInertia = linear;
    def.stain.switches.coriolis = coriolis;
    Engine e(def);
    const Eigen::Vector3d x0 = centre(e, e.solvent());
    EXPECT_EQ(e.advanceSteps(steps).status, stain::StepStatus::Ok);
    const double t = e.time();
    const Eigen::Vector3d w = def.rigid.angularVelocity;
    const Eigen::Vector3d ball = x0 + w.cross(x0 - def.rigid.pivot) * t;
    const Eigen::Vector3d x = centre(e, e.solvent());
    // Back to the rest frame: rotate by −ω t about the pivot.
    const Eigen::Matrix3d back = Eigen::AngleAxisd(-w.norm() * t, w.normalized()).toRotationMatrix();
    return Result{(x - ball).norm(), back * (x - def.rigid.pivot) - (x0 - def.rigid.pivot)};
  };
  const Result none = run(false, false), translation = run(true, false), full = run(true, true);
  std::printf("  miss: none %.4f m, translational %.4f m, full %.4f m; turn (z of cross) %.3g\n", none.miss,
              translation.miss, full.miss, translation.material.cross(full.material).z());
  EXPECT_LT(full.miss, 0.3 * translation.miss);
  EXPECT_LT(full.miss, 0.3 * none.miss);
  EXPECT_LT(none.material.norm(), 0.2 * translation.material.norm()) << "without inertia the liquid stays put";
  EXPECT_LT(translation.material.cross(full.material).z(), 0.0) << "Coriolis turns the trail right";
}

// Fig. 12: with fast absorption, a higher saturation density stops the liquid
// sooner: a smaller stained area.
TEST(DemoScenes, HigherSaturationGivesASmallerStain) {
  nlohmann::json j = readScene("parameter_grid.json");
  j["mesh"]["patch"]["resolution"] = {24, 24};
  const SceneDef scene = parse(j, "parameter_grid.json");
  const auto stainedFraction = [&](double saturation) {
    EngineDef def = engineDef(scene);
    def.stain.liquid.absorptionRate = 2.5;
    def.stain.liquid.saturationDensity = saturation;
    def.stain.switches.adsorption = false;
    Engine e(def);
    EXPECT_EQ(e.advanceSteps(100).status, stain::StepStatus::Ok);
    const Eigen::VectorXd s = totalSolute(e);
    return double((s.array() > 0.05 * s.maxCoeff()).count()) / double(s.size());
  };
  const double low = stainedFraction(0.3), high = stainedFraction(1.2);
  std::printf("  stained fraction: sat 0.3 %.3f, sat 1.2 %.3f\n", low, high);
  EXPECT_GT(low, 1.1 * high) << "stained fraction at sat 0.3: " << low << ", at 1.2: " << high;
}

// Fig. 13: the same with adsorption alone: a higher capacity A_d at K_d = 2.5/s
// holds the solute sooner.
TEST(DemoScenes, HigherAdsorptionCapacityGivesASmallerStain) {
  nlohmann::json j = readScene("parameter_grid.json");
  j["mesh"]["patch"]["resolution"] = {24, 24};
  const SceneDef scene = parse(j, "parameter_grid.json");
  const auto stainedFraction = [&](double capacity) {
    EngineDef def = engineDef(scene);
    def.stain.liquid.desorptionRate = 2.5;
    def.stain.liquid.adsorptionCapacity = capacity;
    def.stain.switches.absorption = false;
    Engine e(def);
    EXPECT_EQ(e.advanceSteps(100).status, stain::StepStatus::Ok);
    const Eigen::VectorXd s = totalSolute(e);
    return double((s.array() > 0.05 * s.maxCoeff()).count()) / double(s.size());
  };
  const double low = stainedFraction(0.1), high = stainedFraction(0.4);
  std::printf("  stained fraction: A_d 0.1 %.3f, A_d 0.4 %.3f\n", low, high);
  EXPECT_GT(low, 1.1 * high);
}


/// Principal spread of `weight` about its centre, in the plane z = 0: the
/// weighted second moments along the unit directions d1 and d2 (m²).
Eigen::Vector2d spreadAlong(const Engine& e, const Eigen::VectorXd& weight, const Eigen::Vector3d& d1,
                            const Eigen::Vector3d& d2) {
  const Eigen::Vector3d c = centre(e, weight);
  double a = 0, b = 0, total = 0;
  for (Eigen::Index v = 0; v < weight.size(); ++v) {
    const Eigen::Vector3d r = e.positions().row(v).transpose() - c;
    a += weight[v] * std::pow(r.dot(d1.normalized()), 2);
    b += weight[v] * std::pow(r.dot(d2.normalized()), 2);
    total += weight[v];
  }
  return Eigen::Vector2d(a, b) / total;
}

// Fig. 11 (a-c): the tensor diffuses 5 times faster along the diagonal weft, so
// both stains are elongated along (1, 1) (diffusion alone by more than 1.5x
// in second moment). Diffusion alone keeps the centre
// darkest; with absorption, adsorption, evaporation and an outward impact
// velocity the liquid is fixed where it stops, and the rim (the darkest
// vertex, at least 1.5 drop radii out) ends more than 10% darker than the centre: a halo.
TEST(DemoScenes, AnisotropicStainIsElongatedAndInteractionsMakeAHalo) {
  // Both scenes are one pipette drop landing over `radius` (4 mm); distances
  // below are in drop radii. Each runs its own simulated time.
  const double dropRadius = readScene("anisotropy.json")["drops"][0]["radius"].get<double>();
  const auto run = [](const char* file) {
    nlohmann::json j = readScene(file);
    j["mesh"]["patch"]["resolution"] = {30, 30};
    auto e = std::make_unique<Engine>(engineDef(parse(j, file)));
    const int steps = j["outputs"]["frames"].get<int>() * j["outputs"]["steps_per_frame"].get<int>();
    EXPECT_EQ(e->advanceSteps(steps).status, stain::StepStatus::Ok) << file;
    return e;
  };
  const auto plain = run("anisotropy.json");
  const auto interacting = run("anisotropy_halo.json");
  // The halo's random impact profile (splash_seed 0) blurs the anisotropy,
  // so it is only required to be longer along the weft than across.
  const Eigen::Vector2d sp = spreadAlong(*plain, totalSolute(*plain), {1, 1, 0}, {1, -1, 0});
  EXPECT_GT(sp[0], 1.5 * sp[1]) << "second moments along / across the weft: " << sp.transpose();
  const Eigen::Vector2d si = spreadAlong(*interacting, totalSolute(*interacting), {1, 1, 0}, {1, -1, 0});
  EXPECT_GT(si[0], si[1]) << "second moments along / across the weft: " << si.transpose();
  // Solute at the drop's centre vertex (the nearest to the origin) and the
  // darkest vertex, in each run.
  const auto centreAndPeak = [](const Engine& e) {
    const Eigen::VectorXd s = totalSolute(e);
    Eigen::Index centreVertex = 0, peakVertex = 0;
    e.positions().rowwise().norm().minCoeff(&centreVertex);
    s.maxCoeff(&peakVertex);
    return std::make_tuple(s[centreVertex], s[peakVertex], e.positions().row(peakVertex).norm());
  };
  const auto [plainCentre, plainPeak, plainPeakRadius] = centreAndPeak(*plain);
  EXPECT_NEAR(plainCentre, plainPeak, 1e-12 + 0.01 * plainPeak) << "diffusion alone: darkest at the centre";
  EXPECT_LT(plainPeakRadius, 0.375 * dropRadius);
  const auto [haloCentre, haloPeak, haloPeakRadius] = centreAndPeak(*interacting);
  std::printf("  halo: centre %.3f, rim %.3f kg/m^2 at %.3f m; weft/cross moments %.2f (plain), %.2f (halo)\n",
              haloCentre, haloPeak, haloPeakRadius, sp[0] / sp[1], si[0] / si[1]);
  EXPECT_LT(haloCentre, 0.9 * haloPeak) << "halo: centre " << haloCentre << ", rim " << haloPeak << " kg/m^2";
  EXPECT_GT(haloPeakRadius, 1.5 * dropRadius);
}

// Fig. 11 (d): at the corner where three patterns meet, the two right-hand
// patches (satin above, basket below) would hold mirror-image stains if their
// fabrics were equal; their different tensors must make the solute masses on
// the two sides differ by more than 2%.
TEST(DemoScenes, ThreePatternCornerSpreadsDifferentlyIntoEachPatch) {
  const SceneDef scene = loadScene(kScenes + "three_patterns_corner.json");
  Engine e(engineDef(scene));
  ASSERT_EQ(e.advanceSteps(60).status, stain::StepStatus::Ok);
  const Eigen::VectorXd s = totalSolute(e);
  // A band of 2.5 % of the square's width around the seams is left out (the scene is scaled).
  const double margin = 0.025 * (e.positions().col(0).maxCoeff() - e.positions().col(0).minCoeff());
  double above = 0, below = 0;
  for (Eigen::Index v = 0; v < s.size(); ++v) {
    const double x = e.positions()(v, 0), y = e.positions()(v, 1);
    if (x > margin && y > margin) above += s[v];
    if (x > margin && y < -margin) below += s[v];
  }
  std::printf("  corner: satin side %.4g, basket side %.4g (sums of kg/m^2)\n", above, below);
  EXPECT_GT(std::abs(above - below), 0.02 * (above + below)) << "satin side " << above << ", basket side " << below;
  EXPECT_LT(std::abs(e.statistics().massBudget.soluteError()), 1e-9);
}


// docs/gallery.md, "Drop sizes": every example scene's drops land as a film
// about a millimetre thick, h = V / (pi r^2) with V = (solvent + solute) / rho,
// and are a drop (<= 0.1 ml), a spill (a few ml) or a glass (tens of ml), never
// a glass's worth in a drop's radius. The band 0.5-3.5 mm holds every scene
// (0.96-3.1 mm); a 30 ml drop over 4 mm (600 mm) or 0.05 ml over 10 cm
// (0.002 mm) fails.
TEST(DemoScenes, EveryExampleDropLandsAsAFilmAboutAMillimetreThick) {
  int drops = 0;
  for (const auto& entry : std::filesystem::directory_iterator(kScenes)) {
    if (entry.path().extension() != ".json") continue;
    const std::string file = entry.path().filename().string();
    const SceneDef scene = loadScene(entry.path().string());
    const double rho = scene.engine.stain.liquid.liquidDensity;
    for (const TimedDrop& d : scene.engine.drops) {
      const double volume = (d.drop.solventMass + d.drop.soluteMass) / rho;
      const double film = volume / (M_PI * d.drop.radius * d.drop.radius);
      EXPECT_GT(film, 0.5e-3) << file << ": " << volume * 1e6 << " ml over " << d.drop.radius << " m";
      EXPECT_LT(film, 3.5e-3) << file << ": " << volume * 1e6 << " ml over " << d.drop.radius << " m";
      EXPECT_LT(volume, 0.1e-3) << file << ": a drop of more than 100 ml";
      ++drops;
    }
  }
  EXPECT_GT(drops, 20);
}

// The preview keys the gallery scenes use: rest_shape and up (checked against
// the view direction, with the key path in the message).
TEST(DemoScenes, PreviewUpAndRestShapeKeys) {
  nlohmann::json j = readScene("rotating_bunny.json");
  const SceneDef scene = parse(j, "rotating_bunny.json");
  EXPECT_EQ(scene.outputs.preview.up, Eigen::Vector3d(0, 1, 0));
  EXPECT_FALSE(scene.outputs.preview.restShape);
  j["outputs"]["preview"]["up"] = {2, -1.6, 0.6};  // parallel to view_direction [1, -0.8, 0.3]
  try {
    parse(j, "rotating_bunny.json");
    ADD_FAILURE() << "an up parallel to the view was accepted";
  } catch (const SceneError& e) {
    EXPECT_NE(std::string(e.what()).find("outputs.preview.up"), std::string::npos) << e.what();
  }
}

}  // namespace
}  // namespace blot::engine
