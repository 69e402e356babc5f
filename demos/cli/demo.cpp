// `blot demo NAME`: small self-contained demos that write pictures and caches.
//
// Design note: until scene files drive `blot run`, this command gives users a
// one-line way to see the output side work end to end on a real mesh:
// "drop-diffusion" puts a drop of solute on a mesh (the bunny by default,
// the drop on its back) and
// diffuses it isotropically with the paper's implicit scheme
// (M + h D L) σ^{t+h} = M σ^t (P1 cotan stiffness L, lumped mass M, one
// CHOLMOD factorization reused for every step), then writes a PLY cache per
// frame (solute + Beer–Lambert colour), a contact sheet of the frames, and a
// JSON summary with the mass budget (implicit diffusion conserves Σ M σ, so
// the relative drift printed is a correctness check a user can read).
// Rejected: hiding a full coupled scene here; that belongs to scene files.
#include "assets.h"
#include "commands.h"

#include <blot/cloth/surface_motion.h>
#include <blot/engine/image.h>
#include <blot/engine/ply_frame_writer.h>
#include <blot/engine/renderer.h>
#include <blot/engine/stain_color.h>
#include <blot/stain/fabric/homogenization.h>
#include <blot/stain/geometry/intrinsic_geometry.h>
#include <blot/stain/geometry/mesh_primitives.h>
#include <blot/stain/io/mesh_io.h>
#include <blot/stain/geometry/operators.h>
#include <blot/stain/numerics/sparse_solver.h>
#include <blot/stain/stain_solver.h>
#include <blot/stain/fabric/weave_pattern.h>
#include <blot/stain/geometry/surface_topology.h>

#include <nlohmann/json.hpp>

#include <chrono>
#include <cmath>
#include <cstdio>
#include <exception>
#include <filesystem>
#include <iostream>
#include <memory>
#include <stdexcept>
#include <string>
#include <vector>

namespace blot::cli {
namespace {

struct DemoOptions {
  std::string name = "rotating-cloth";
  std::string meshPath = "build/external/meshes/bunny00.off";  // found by findAsset (assets.h)
  std::string outputDirectory = "out/demo";
  std::string pigment = "wine";
  int frames = 5;               // after the initial one, as in `blot run` and `blot figure`
  int stepsPerFrame = 10;
  double timeStep = 0.01;      // s
  double diffusivity = 0.01;   // m²/s
  double dropDensity = 3.0;    // kg/m² at the centre
  double dropRadius = 0.1;     // m (Gaussian standard deviation)
};

const char* const kDemoNames[] = {"rotating-cloth", "drop-diffusion"};

/// Render settings shared by the demos' preview frames (pixels; 3×3 supersampling).
engine::RenderSettings previewSettings(int width, int height) {
  engine::RenderSettings settings;
  settings.width = width;
  settings.height = height;
  settings.supersampling = 3;
  settings.background = {0.9, 0.91, 0.94};
  return settings;
}

std::string frameLabel(double time) {
  char text[32];
  std::snprintf(text, sizeof text, "t = %.2f s", time);
  return text;
}

int runDropDiffusion(const DemoOptions& options) {
  if (options.frames < 1 || options.stepsPerFrame < 1 || !(options.timeStep > 0.0) ||
      !(options.diffusivity > 0.0)) {
    throw std::invalid_argument("--frames and --steps-per-frame must be >= 1, --dt and "
                                "--diffusivity positive");
  }
  const stain::TriangleMesh mesh = stain::loadMesh(findAsset(options.meshPath));
  const auto vertexCount = static_cast<int>(mesh.vertexPositions.rows());
  const stain::SurfaceTopology topology(mesh.faces, vertexCount, options.meshPath);
  const stain::Vector lengths = stain::edgeLengths(topology, mesh.vertexPositions);
  const stain::Vector areas =
      stain::vertexDualAreas(topology, stain::faceAreas(topology, lengths));
  const stain::Vector weights =
      stain::edgeCotanWeights(topology, stain::faceCornerAngles(topology, lengths));
  const stain::SparseMatrix mass = stain::lumpedMassMatrix(areas);
  const stain::SparseMatrix system =
      mass + (options.timeStep * options.diffusivity) * stain::cotanLaplacian(topology, weights);
  stain::RealCholeskySolver solver;
  if (const stain::SolverStatus status = solver.compute(system);
      status != stain::SolverStatus::Ok) {
    throw std::runtime_error(std::string("diffusion system: ") + stain::toString(status));
  }

  // The drop lands on the highest vertex (+y) of the mesh's +x part: the
  // bunny's back, clear of the ears.
  const Eigen::AlignedBox3d box = engine::boundingBox(mesh.vertexPositions);
  const double xCut = box.center().x() + 0.1 * box.sizes().x();
  int center = -1;
  for (int i = 0; i < vertexCount; ++i) {
    if (mesh.vertexPositions(i, 0) < xCut) continue;
    if (center < 0 || mesh.vertexPositions(i, 1) > mesh.vertexPositions(center, 1)) center = i;
  }
  stain::Vector solute(vertexCount);
  for (int i = 0; i < vertexCount; ++i) {
    const double r2 = (mesh.vertexPositions.row(i) - mesh.vertexPositions.row(center)).squaredNorm();
    solute[i] = options.dropDensity * std::exp(-0.5 * r2 / (options.dropRadius * options.dropRadius));
  }

  std::filesystem::create_directories(options.outputDirectory);
  const engine::PlyFrameWriter plyWriter(options.outputDirectory, "drop_diffusion");
  const engine::StainColorMapping mapping =
      engine::stainColorMapping(engine::pigmentPresetFromName(options.pigment));
  const engine::RenderSettings settings = previewSettings(360, 300);
  const engine::Camera camera = engine::framePoints(
      mesh.vertexPositions, {-0.3, -0.6, -1.0}, double(settings.width) / settings.height);
  engine::Renderer renderer(settings);

  const double initialMass = areas.dot(solute);
  std::vector<engine::Image> images;
  std::vector<std::string> labels;
  nlohmann::json frames = nlohmann::json::array();
  const stain::Vector none;
  Eigen::MatrixX3d colors;
  stain::Vector rhs(vertexCount);
  for (int frame = 0; frame <= options.frames; ++frame) {  // frame 0: the initial state
    if (frame > 0) {
      for (int step = 0; step < options.stepsPerFrame; ++step) {
        rhs = areas.cwiseProduct(solute);
        if (const stain::SolverStatus status = solver.solve(rhs, solute);
            status != stain::SolverStatus::Ok) {
          throw std::runtime_error(std::string("diffusion solve: ") + stain::toString(status));
        }
      }
    }
    const double time = frame * options.stepsPerFrame * options.timeStep;
    engine::stainColors(mapping, none, solute, none, none, colors);
    engine::PlyFrame ply;
    ply.vertexPositions = mesh.vertexPositions;
    ply.faces = mesh.faces;
    ply.vertexAttributes.push_back({"solute", solute, engine::PlyScalarType::Float32});
    ply.vertexColors = engine::vertexColorsToBytes(colors);
    const std::string plyPath = plyWriter.write(frame, ply);
    renderer.beginFrame(camera);
    renderer.drawMesh(mesh.vertexPositions, mesh.faces, colors);
    images.push_back(renderer.finishFrame());
    labels.push_back(frameLabel(time));
    frames.push_back({{"time_s", time},
                      {"solute_mass_kg", areas.dot(solute)},
                      {"max_solute_kg_per_m2", solute.maxCoeff()},
                      {"ply", plyPath}});
  }
  const std::string sheetPath =
      (std::filesystem::path(options.outputDirectory) / "drop_diffusion.png").string();
  engine::ContactSheetOptions sheetOptions;
  sheetOptions.columns = std::min(options.frames + 1, 3);
  sheetOptions.labelScale = 2;
  engine::writePng(engine::contactSheet(images, labels, sheetOptions), sheetPath);

  const double finalMass = areas.dot(solute);
  const nlohmann::json summary = {
      {"demo", "drop-diffusion"},
      {"mesh", options.meshPath},
      {"vertices", vertexCount},
      {"pigment", options.pigment},
      {"diffusivity_m2_per_s", options.diffusivity},
      {"time_step_s", options.timeStep},
      {"initial_solute_mass_kg", initialMass},
      {"final_solute_mass_kg", finalMass},
      {"relative_mass_drift", std::abs(finalMass - initialMass) / initialMass},
      {"frames", frames},
      {"contact_sheet", sheetPath}};
  std::cout << summary.dump(2) << "\n";
  return 0;
}


/// Mean milliseconds per step of each stage, from the per-step profiles.
struct ProfileSums {
  stain::StepProfile sum;  // stage times summed with StepProfile::addTimes
  int steps = 0;
  void add(const stain::StepProfile& p) {
    sum.addTimes(p);
    ++steps;
  }
  nlohmann::json meansJson() const {
    const double n = steps > 0 ? steps : 1;
    nlohmann::json means = stageTimesJson(sum.milliseconds, n, "");
    means["total"] = sum.total / n;
    return means;
  }
};

// "rotating-cloth": a square of twill spinning at 2 rad/s about its centre
// (the paper's rotating-cloth scene, Table 1, at 2.4K vertices). A drop of
// wine lands at rest on the cloth off-centre; the centrifugal force drives it
// outward and the Coriolis force bends its trail to the right of the outward
// direction (the cloth turns counter-clockwise), while the homogenized twill
// tensor stretches the stain along the weft. Everything runs through the
// StainSolver: Kabsch frames, inertial forces, advection, implicit
// anisotropic diffusion, absorption/adsorption/evaporation.
int runRotatingCloth(const DemoOptions& options) {
  if (options.frames < 1 || options.stepsPerFrame < 1 || !(options.timeStep > 0.0))
    throw std::invalid_argument("--frames and --steps-per-frame must be >= 1 and --dt positive");
  stain::TriangleMesh mesh = stain::gridMesh(48, 48, 1.0, 1.0);
  mesh.vertexPositions.col(0).array() -= 0.5;
  mesh.vertexPositions.col(1).array() -= 0.5;
  const auto vertexCount = static_cast<int>(mesh.vertexPositions.rows());
  const stain::SurfaceTopology topology(mesh.faces, vertexCount, "rotating-cloth grid");

  // Twill 2/1 with the default pair coefficients (1..500), scaled to m²/s.
  const stain::HomogenizationResult twill = stain::homogenize(stain::presetWeavePattern("twill-2-1"));
  const stain::Matrix2 tensor = twill.effective * (options.diffusivity / twill.effective.trace());
  stain::FabricField fabric;
  fabric.densityTensors.resize(mesh.faces.rows(), 3);
  fabric.velocityTensors.resize(mesh.faces.rows(), 3);
  fabric.weftDirections.resize(mesh.faces.rows(), 3);
  for (int f = 0; f < mesh.faces.rows(); ++f) {
    fabric.densityTensors.row(f) << tensor(0, 0), tensor(0, 1), tensor(1, 1);
    fabric.velocityTensors.row(f) << 2e-3, 0.0, 2e-3;
    fabric.weftDirections.row(f) << 1.0, 0.0, 0.0;
  }
  stain::StainSolverDef def;
  def.gravity = stain::Vector3(0, 0, -9.8);
  def.liquid.absorptionRate = 0.4;
  def.liquid.saturationDensity = 1.5;
  def.liquid.evaporationRate = 0.004;
  stain::StainSolver solver(topology, mesh.vertexPositions, fabric, def);

  cloth::RigidMotionDef motionDef;
  motionDef.angularVelocity = {0.0, 0.0, 2.0};
  cloth::RigidMotion motion(mesh.vertexPositions, motionDef);
  solver.setInitialMotion(motion.positions(), motion.velocities());
  stain::DropDef drop;
  drop.centerPoint = stain::Vector3(0.12, 0.0, 0.0);
  drop.radius = 0.06;
  drop.solventMass = 0.02;
  drop.soluteMass = 0.015;
  solver.addDrop(drop);

  std::filesystem::create_directories(options.outputDirectory);
  const engine::PlyFrameWriter plyWriter(options.outputDirectory, "rotating_cloth");
  const engine::StainColorMapping mapping =
      engine::stainColorMapping(engine::pigmentPresetFromName(options.pigment));
  const engine::RenderSettings settings = previewSettings(320, 320);
  // The stain on the rest shape, seen from above: the cloth's own frame.
  const engine::Camera camera = engine::framePoints(mesh.vertexPositions, {0.0, 0.0, -1.0}, 1.0,
                                                    engine::Projection::Orthographic);
  engine::Renderer renderer(settings);

  std::vector<engine::Image> images;
  std::vector<std::string> labels;
  nlohmann::json frames = nlohmann::json::array();
  Eigen::MatrixX3d colors;
  stain::RowVectors3 worldVelocities(vertexCount, 3), relativeVelocities(vertexCount, 3);
  ProfileSums sums;
  const auto start = std::chrono::steady_clock::now();
  for (int frame = 0; frame <= options.frames; ++frame) {  // frame 0: the initial state
    for (int step = 0; frame > 0 && step < options.stepsPerFrame; ++step) {
      motion.advance(options.timeStep);
      // The motion is known rigid: the solver takes its rotation instead of
      // fitting one per vertex.
      const stain::StepReport report =
          solver.stepRigid(options.timeStep, motion.positions(), motion.rotationAt(motion.time()));
      if (report.status != stain::StepStatus::Ok)
        throw std::runtime_error("step " + std::to_string(solver.stepCount() + 1) + " failed in stage '" +
                                 report.stageName() + "': " + report.message);
      sums.add(solver.profile());
    }
    const stain::StainState& s = solver.state();
    const stain::ExtrinsicGeometry& geometry = solver.geometry().extrinsic();
    for (int i = 0; i < vertexCount; ++i) {
      worldVelocities.row(i) = solver.worldVelocity(i).transpose();
      relativeVelocities.row(i) = solver.relativeVelocity(i).transpose();
    }
    engine::stainColors(mapping, s.solvent, s.solute, s.absorbedSolute, s.adsorbedSolute, colors);
    engine::PlyFrame ply;
    ply.vertexPositions = geometry.nextPositions;
    ply.faces = mesh.faces;
    ply.vertexAttributes = {{"solvent", s.solvent, engine::PlyScalarType::Float32},
                            {"solute", s.solute, engine::PlyScalarType::Float32},
                            {"absorbed_solvent", s.absorbedSolvent, engine::PlyScalarType::Float32},
                            {"absorbed_solute", s.absorbedSolute, engine::PlyScalarType::Float32},
                            {"adsorbed_solute", s.adsorbedSolute, engine::PlyScalarType::Float32}};
    for (auto& attribute : engine::velocityAttributes(worldVelocities)) ply.vertexAttributes.push_back(attribute);
    for (auto& attribute : engine::relativeVelocityAttributes(relativeVelocities))
      ply.vertexAttributes.push_back(attribute);
    ply.vertexColors = engine::vertexColorsToBytes(colors);
    const std::string plyPath = plyWriter.write(frame, ply);
    renderer.beginFrame(camera);
    renderer.drawMesh(mesh.vertexPositions, mesh.faces, colors);
    images.push_back(renderer.finishFrame());
    const double time = solver.time();
    labels.push_back(frameLabel(time));
    const stain::MassBudget b = solver.massBudget();
    frames.push_back({{"time_s", time}, {"free_solvent_kg", b.freeSolvent}, {"solute_kg", b.freeSolute},
                      {"ply", plyPath}});
  }
  const double seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  const std::string sheetPath = (std::filesystem::path(options.outputDirectory) / "rotating_cloth.png").string();
  engine::ContactSheetOptions sheetOptions;
  sheetOptions.columns = std::min(options.frames + 1, 4);
  sheetOptions.labelScale = 2;
  engine::writePng(engine::contactSheet(images, labels, sheetOptions), sheetPath);

  const stain::MassBudget b = solver.massBudget();
  const nlohmann::json summary = {
      {"demo", "rotating-cloth"},
      {"vertices", vertexCount},
      {"faces", mesh.faces.rows()},
      {"pigment", options.pigment},
      {"fabric", {{"pattern", "twill-2-1"},
                  {"effective_tensor_m2_per_s", {{tensor(0, 0), tensor(0, 1)}, {tensor(1, 0), tensor(1, 1)}}}}},
      {"angular_velocity_rad_per_s", 2.0},
      {"time_step_s", options.timeStep},
      {"steps", solver.stepCount()},
      {"steps_per_second", seconds > 0 ? solver.stepCount() / seconds : 0.0},
      {"mean_ms_per_step", sums.meansJson()},
      {"mass_budget_kg",
       {{"solvent", {{"added", b.addedSolvent}, {"free", b.freeSolvent}, {"absorbed", b.absorbedSolvent},
                     {"evaporated", b.evaporatedSolvent}, {"relative_error", b.solventError()}}},
        {"solute", {{"added", b.addedSolute}, {"free", b.freeSolute}, {"absorbed", b.absorbedSolute},
                    {"adsorbed", b.adsorbedSolute}, {"relative_error", b.soluteError()}}}}},
      {"frames", frames},
      {"contact_sheet", sheetPath}};
  std::cout << summary.dump(2) << "\n";
  std::cerr << "blot demo: wrote " << sheetPath << " and " << options.frames + 1 << " PLY frames in "
            << options.outputDirectory << "\n";
  return 0;
}

int runDemo(const DemoOptions& options) {
  try {
    if (options.name == "rotating-cloth") return runRotatingCloth(options);
    if (options.name == "drop-diffusion") return runDropDiffusion(options);
    std::string known;
    for (const char* name : kDemoNames) known += std::string(known.empty() ? "" : ", ") + name;
    throw std::invalid_argument("unknown demo '" + options.name + "' (available: " + known + ")");
  } catch (const std::exception& error) {
    std::cerr << "blot demo: error: " << error.what() << "\n";
    return 1;
  }
}

}  // namespace

void registerDemoCommand(CLI::App& app, int& exitCode) {
  auto options = std::make_shared<DemoOptions>();
  CLI::App* command = app.add_subcommand(
      "demo", "Run a built-in demo; writes PLY frames and a PNG contact sheet, prints JSON. "
              "Demos: rotating-cloth (default), drop-diffusion");
  command->add_option("name", options->name, "Demo name")->capture_default_str();
  command->add_option("--mesh", options->meshPath, "Mesh file")->capture_default_str();
  command->add_option("--out", options->outputDirectory, "Output folder (created)")->capture_default_str();
  // The old name, hidden: --out is the name every command uses.
  command->add_option("--output", options->outputDirectory, "Same as --out")->group("");
  command->add_option("--pigment", options->pigment, "wine, coffee or ink")->capture_default_str();
  command->add_option("--frames", options->frames, "Frames after the initial one (frames 0..N are written)")
      ->capture_default_str();
  command->add_option("--steps-per-frame", options->stepsPerFrame, "Time steps per frame")->capture_default_str();
  command->add_option("--dt", options->timeStep, "Time step (s)")->capture_default_str();
  command->add_option("--diffusivity", options->diffusivity, "Isotropic diffusivity (m^2/s)")->capture_default_str();
  command->callback([options, &exitCode]() { exitCode = runDemo(*options); });
}

}  // namespace blot::cli
