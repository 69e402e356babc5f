// `blot figure NAME`: paper figures that are more than one scene run, drawn
// as one labelled picture.
//
// Design note: each figure is a base scene file (assets/scenes/) run several
// times with one thing changed, so the scene format stays the single place a
// setup is described and `blot run` on the base file reproduces any panel.
//   fig5: the rotating planar region (assets/scenes/rotating_region.json) with
//     no inertial forces / translational inertia only / full inertia. The
//     liquid's centre of mass x̄ = Σ A_i σ_i x_i / Σ A_i σ_i (free solvent,
//     vertex areas A_i = Σ |face|/3 on the current shape) is tracked each frame
//     in the world (inertial) frame and drawn with the path of a free particle
//     that starts there with the cloth's velocity, x0 + (ω × (x0 − c)) t: the
//     liquid starts at rest on the cloth, so without diffusion and friction an
//     inertially correct fluid's centre follows that straight line.
//   parameter-grid: a static drop (assets/scenes/parameter_grid.json) on a
//     3 x 3 grid of absorption K_p x σ_sat (Fig. 12) or adsorption K_d x A_d
//     (Fig. 13), rendered from above into a labelled contact sheet.
// Rejected: hard-coding the setups here (a second description of the same
// scene that would drift from the files users run).
#include "assets.h"
#include "commands.h"

#include <blot/engine/engine.h>
#include <blot/engine/frame_writer.h>
#include <blot/engine/scene.h>
#include <blot/stain/io/atomic_file.h>
#include <blot/stain/thread_limit.h>
#include <blot/stain/io/strict_json.h>

#include <nlohmann/json.hpp>
#include <omp.h>

#include <cstdio>
#include <filesystem>
#include <fstream>
#include <iostream>
#include <memory>
#include <stdexcept>
#include <string>
#include <vector>

namespace blot::cli {
namespace {

struct FigureOptions {
  std::string name;
  std::string kind = "absorption";
  std::string scenePath;        // empty: the figure's default scene under assets/scenes/
  std::string outputDirectory;  // empty: out/<figure>
  int frames = 0;               // 0: the scene's outputs.frames
  int width = 240;              // pixels per panel
  int threads = 1;
};

/// Weighted centre of `weight` (kg/m²) over the surface, world frame (m);
/// vertex areas are a third of the adjacent faces' areas on the current shape.
Eigen::Vector3d weightedCentre(const engine::Engine& e, const Eigen::VectorXd& weight) {
  const Eigen::MatrixX3d& x = e.positions();
  const stain::Triangles& f = e.faces();
  Eigen::VectorXd area = Eigen::VectorXd::Zero(x.rows());
  for (Eigen::Index t = 0; t < f.rows(); ++t) {
    const double a = 0.5 * (x.row(f(t, 1)) - x.row(f(t, 0))).cross(x.row(f(t, 2)) - x.row(f(t, 0))).norm();
    for (int k = 0; k < 3; ++k) area[f(t, k)] += a / 3.0;
  }
  const Eigen::VectorXd m = area.cwiseProduct(weight.cwiseMax(0.0));
  const double total = m.sum();
  if (!(total > 0)) throw std::runtime_error("no liquid on the surface to take the centre of");
  return (x.transpose() * m) / total;
}

/// The scene's preview of `e` at width x width pixels, with `paths` drawn on top.
engine::Image renderPanel(const engine::Engine& e, int width, const engine::ScenePreview& scenePreview,
                          const std::vector<stain::RowVectors3>& paths, const std::vector<engine::Color>& pathColors) {
  engine::ScenePreview preview = scenePreview;
  preview.width = preview.height = width;
  preview.supersampling = 3;
  return engine::renderPreview(e, preview, engine::PreviewShape::Current, [&](engine::Renderer& renderer) {
    for (std::size_t i = 0; i < paths.size(); ++i) {
      if (paths[i].rows() < 2) continue;
      engine::LineStyle style;
      style.color = pathColors[i];
      style.width = 2.5;
      style.depthTest = false;
      renderer.drawPolyline(paths[i], style);
      style.width = 7.0;
      renderer.drawPoints(paths[i].bottomRows(1), style);
    }
  });
}

/// Default base scenes: assets/scenes/ wherever `blot` finds its assets (assets.h).
std::string defaultScene(const std::string& file) { return findAsset("assets/scenes/" + file); }

/// summary.json through the atomic writer, every write checked (an unchecked
/// ofstream wrote nothing into a folder named summary.json, exit 0, and hung
/// on a named pipe there).
void writeSummary(const std::string& directory, const nlohmann::json& summary) {
  const std::string text = stain::dumpJson(summary, 2) + "\n";
  stain::writeFileAtomically((std::filesystem::path(directory) / "summary.json").string(), text.data(), text.size());
}

int runFig5(const FigureOptions& o) {
  const std::string scenePath = o.scenePath.empty() ? defaultScene("rotating_region.json") : o.scenePath;
  const engine::SceneDef base = engine::loadScene(scenePath);
  if (base.engine.source != engine::MotionSource::Rigid) {
    std::cerr << "blot figure fig5: error: " << scenePath << ": cloth.source must be \"rigid\"\n";
    return 1;
  }
  const std::string directory = o.outputDirectory.empty() ? "out/fig5" : o.outputDirectory;
  std::filesystem::create_directories(directory);
  const int frames = o.frames > 0 ? o.frames : base.outputs.frames;
  const double frameTime = base.outputs.stepsPerFrame * base.engine.timeStep;

  struct Variant {
    const char* label;
    bool linearInertia, coriolis;
  };
  const Variant variants[] = {{"a: no inertial forces", false, false},
                              {"b: translational only", true, false},
                              {"c: full (with Coriolis)", true, true}};
  const engine::Color pathColor(0.85, 0.1, 0.1), ballColor(0.1, 0.3, 0.9);
  std::vector<engine::Image> panels;
  std::vector<std::string> labels;
  nlohmann::json results = nlohmann::json::array();
  for (const Variant& v : variants) {
    engine::EngineDef def = base.engine;
    def.stain.switches.linearInertia = v.linearInertia;
    def.stain.switches.coriolis = v.coriolis;
    engine::Engine e(def);
    const Eigen::Vector3d x0 = weightedCentre(e, e.solvent());
    const cloth::RigidMotionDef& r = def.rigid;
    const Eigen::Vector3d v0 = r.angularVelocity.cross(x0 - r.pivot) + r.linearVelocity;
    stain::RowVectors3 path(frames + 1, 3), ball(frames + 1, 3);
    path.row(0) = x0.transpose();
    ball.row(0) = x0.transpose();
    for (int k = 1; k <= frames; ++k) {
      const stain::StepReport report = e.advanceSteps(base.outputs.stepsPerFrame);
      if (report.status != stain::StepStatus::Ok) {
        std::cerr << "blot figure fig5: numerical failure (" << v.label << "), stage '" << report.stageName()
                  << "': " << report.message << "\n";
        return 3;
      }
      const double t = k * frameTime;
      path.row(k) = weightedCentre(e, e.solvent()).transpose();
      ball.row(k) = (x0 + v0 * t + 0.5 * r.linearAcceleration * t * t).transpose();
    }
    const double miss = (path.bottomRows(1) - ball.bottomRows(1)).norm();
    const double travelled = (ball.bottomRows(1) - ball.topRows(1)).norm();
    results.push_back({{"variant", v.label},
                       {"linear_inertia", v.linearInertia},
                       {"coriolis", v.coriolis},
                       {"final_centre_m", {path(frames, 0), path(frames, 1), path(frames, 2)}},
                       {"free_particle_m", {ball(frames, 0), ball(frames, 1), ball(frames, 2)}},
                       {"distance_to_free_particle_m", miss},
                       {"free_particle_travel_m", travelled}});
    panels.push_back(renderPanel(e, o.width, base.outputs.preview, {ball, path}, {ballColor, pathColor}));
    char label[96];
    std::snprintf(label, sizeof label, "%s, miss %.3f m", v.label, miss);
    labels.emplace_back(label);
  }
  const std::string png = (std::filesystem::path(directory) / "fig5_rotating_region.png").string();
  engine::writePng(engine::sideBySide(panels, labels), png);
  const nlohmann::json summary = {{"scene", scenePath}, {"frames", frames}, {"time_s", frames * frameTime},
                                  {"variants", results},
                                  {"legend", "red: liquid centre of mass (world frame); blue: free particle"},
                                  {"png", png}};
  writeSummary(directory, summary);
  std::cout << stain::dumpJson(summary, 2) << "\n";
  return 0;
}

int runParameterGrid(const FigureOptions& o) {
  const bool absorption = o.kind == "absorption";
  if (!absorption && o.kind != "adsorption") {
    std::cerr << "blot figure parameter-grid: error: --kind must be absorption or adsorption, got '" << o.kind << "'\n";
    return 1;
  }
  const std::string scenePath = o.scenePath.empty() ? defaultScene("parameter_grid.json") : o.scenePath;
  const engine::SceneDef base = engine::loadScene(scenePath);
  const std::string directory = o.outputDirectory.empty() ? "out/parameter_grid_" + o.kind : o.outputDirectory;
  std::filesystem::create_directories(directory);
  const int frames = o.frames > 0 ? o.frames : base.outputs.frames;
  // Rows: rate increasing downwards; columns: capacity increasing to the
  // right (the paper's layout). Fig. 12: K_p (1/s) x σ_sat (kg/m²);
  // Fig. 13: K_d (1/s) x A_d (kg/m²), with absorption off so that only
  // adsorption leaves solute behind.
  const double rates[] = {0.1, 0.5, 2.5};
  const std::vector<double> caps = absorption ? std::vector<double>{0.3, 0.6, 1.2} : std::vector<double>{0.1, 0.2, 0.4};
  std::vector<engine::Image> panels;
  std::vector<std::string> labels;
  nlohmann::json cells = nlohmann::json::array();
  for (double rate : rates) {
    for (double cap : caps) {
      engine::EngineDef def = base.engine;
      stain::LiquidParameters& l = def.stain.liquid;
      if (absorption) {
        l.absorptionRate = rate;
        l.saturationDensity = cap;
        def.stain.switches.adsorption = false;
      } else {
        l.desorptionRate = rate;
        l.adsorptionCapacity = cap;
        def.stain.switches.absorption = false;
      }
      engine::Engine e(def);
      const stain::StepReport report = e.advanceSteps(frames * base.outputs.stepsPerFrame);
      if (report.status != stain::StepStatus::Ok) {
        std::cerr << "blot figure parameter-grid: numerical failure at rate " << rate << ", capacity " << cap
                  << ": " << report.message << "\n";
        return 3;
      }
      // Stain extent: area fraction of the mesh that any solute reached.
      const Eigen::VectorXd solute = e.solute() + e.absorbedSolute() + e.adsorbedSolute();
      const double peak = solute.maxCoeff();
      const double stained = double((solute.array() > 0.05 * peak).count()) / double(solute.size());
      cells.push_back({{"rate", rate}, {"capacity", cap}, {"stained_vertex_fraction", stained}, {"peak_solute", peak}});
      panels.push_back(renderPanel(e, o.width, base.outputs.preview, {}, {}));
      char label[64];
      std::snprintf(label, sizeof label, absorption ? "Kp %.2g  sat %.2g" : "Kd %.2g  Ad %.2g", rate, cap);
      labels.emplace_back(label);
    }
  }
  engine::ContactSheetOptions sheet;
  sheet.columns = 3;
  const std::string png = (std::filesystem::path(directory) / ("parameter_grid_" + o.kind + ".png")).string();
  engine::writePng(engine::contactSheet(panels, labels, sheet), png);
  const nlohmann::json summary = {{"scene", scenePath}, {"kind", o.kind}, {"frames", frames}, {"cells", cells},
                                  {"png", png}};
  writeSummary(directory, summary);
  std::cout << stain::dumpJson(summary, 2) << "\n";
  return 0;
}

}  // namespace

void registerFigureCommand(CLI::App& app, int& exitCode) {
  auto options = std::make_shared<FigureOptions>();
  CLI::App* command = app.add_subcommand(
      "figure", "Paper figures made of several runs of a scene: fig5 (rotating region), parameter-grid (Figs. 12, 13)");
  command->add_option("name", options->name, "fig5 or parameter-grid")->required()->check(
      CLI::IsMember({"fig5", "parameter-grid"}));
  CLI::Option* kind = command->add_option("--kind", options->kind, "parameter-grid: absorption (Fig. 12) or adsorption (Fig. 13)")
      ->capture_default_str()
      ->check(CLI::IsMember({"absorption", "adsorption"}));
  command->add_option("--scene", options->scenePath, "Base scene (default: the figure's file in assets/scenes/)")
      ->transform(assetPath());
  command->add_option("--out", options->outputDirectory, "Output folder (default: out/<figure>)")
      ->check(outputFolder());
  command->add_option("--frames", options->frames, "Frames to run (default: the scene's outputs.frames)")
      ->check(CLI::Range(0, 1000000));
  // 2048: a square panel at the renderer's largest supersampling (4) keeps
  // within its sample budget (output_options.h: 2048^2 x 4^2 = 2^26).
  command->add_option("--width", options->width, "Pixels per panel (16 to 2048)")
      ->capture_default_str()
      ->check(CLI::Range(16, 2048));
  command->add_option("--threads", options->threads, "OpenMP threads (0: all cores, at most 1024)")
      ->capture_default_str()
      ->check(CLI::Range(0, stain::kMaxThreads));
  command->callback([options, kind, &exitCode]() {
    // fig5 has no kinds: an ignored --kind would look as if it chose one.
    if (options->name != "parameter-grid" && kind->count() > 0) {
      std::cerr << "blot figure " << options->name << ": error: --kind is for parameter-grid only\n";
      exitCode = 2;
      return;
    }
    if (options->threads > 0) omp_set_num_threads(options->threads);
    try {
      exitCode = options->name == "fig5" ? runFig5(*options) : runParameterGrid(*options);
    } catch (const std::exception& e) {
      std::cerr << "blot figure " << options->name << ": error: " << e.what() << "\n";
      exitCode = 1;
    }
  });
}

}  // namespace blot::cli
