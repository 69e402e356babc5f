// `blot demo NAME`: a shipped scene run through blot::Engine, written with the
// FrameWriter that `blot run` uses (PLY frames, previews, mass budget), plus a
// labelled contact sheet of every frame's preview and a JSON summary.
//
// A demo is a scene file in assets/scenes/ and the shape its contact sheet shows
// the stain on; the command line overrides what a user varies when trying one
// out (frames, steps, time step, diffusivity, pigment).
#include "assets.h"
#include "commands.h"

#include <blot/engine/engine.h>
#include <blot/engine/frame_writer.h>
#include <blot/engine/output_options.h>
#include <blot/engine/scene.h>
#include <blot/engine/stain_color.h>
#include <blot/stain/io/strict_json.h>

#include <nlohmann/json.hpp>

#include <algorithm>
#include <cstdio>
#include <exception>
#include <filesystem>
#include <iostream>
#include <memory>
#include <sstream>
#include <stdexcept>
#include <string>
#include <vector>

namespace blot::cli {
namespace {

struct Demo {
  const char* name;
  const char* sceneFile;  ///< in assets/scenes/, found by findAsset (assets.h)
  /// The contact sheet's shape: the rest shape shows a moving cloth's stain in
  /// the cloth's own frame.
  engine::PreviewShape shape;
  int columns;
};

// rotating-cloth: the paper's rotating-cloth scene (Table 1) at 2.4K vertices:
// a square of twill spinning at 2 rad/s; the wine drop is flung outward, bent
// by the Coriolis force and stretched along the weft (Kabsch-free known
// rotation, inertial forces, advection, anisotropic diffusion, interaction).
// drop-diffusion: a drop on the still bunny, isotropic implicit diffusion only.
const Demo kDemos[] = {
    {"rotating-cloth", "rotating_cloth.json", engine::PreviewShape::Rest, 4},
    {"drop-diffusion", "drop_diffusion.json", engine::PreviewShape::Current, 3},
};

struct DemoOptions {
  std::string name = "rotating-cloth";
  std::string scenePath;  // empty: the demo's scene
  std::string outputDirectory = "out/demo";
  std::string pigment;    // empty: the scene's
  int frames = 5;         // after the initial one, as in `blot run` and `blot figure`
  int stepsPerFrame = 0;  // 0: the scene's
  double timeStep = 0;    // s; 0: the scene's
  double diffusivity = 0; // m²/s; 0: the scene's
};

/// The contact sheet holds every frame's preview in memory: at most this many
/// frames after the initial one.
constexpr int kMaxDemoFrames = 100;
/// --steps-per-frame, as the scene key outputs.steps_per_frame.
constexpr int kMaxStepsPerFrame = 1000000;

/// An option that is 0 (the scene's value) or in [low, high] (low = 0: in
/// (0, high]); the message names the value and the accepted range (CLI11
/// prefixes the option's name).
CLI::Validator zeroOr(double low, double high, const std::string& unit) {
  std::ostringstream range;
  range << "expected 0 (the scene's) or ";
  if (low > 0) range << low << " to " << high << unit;
  else range << "a positive value up to " << high << unit;
  const std::string expected = range.str();
  return CLI::Validator(
      [=](std::string& text) -> std::string {
        double value = 0;
        try {
          std::size_t used = 0;
          value = std::stod(text, &used);
          if (used != text.size()) return text + ": not a number; " + expected;
        } catch (const std::exception&) {
          return text + ": not a number; " + expected;
        }
        if (value == 0 || (value > 0 && value >= low && value <= high)) return "";
        return text + ": " + expected;
      },
      "0 or [" + std::to_string(low) + ", " + std::to_string(high) + "]");
}

const Demo& findDemo(const std::string& name) {
  std::string known;
  for (const Demo& demo : kDemos) {
    if (name == demo.name) return demo;
    known += std::string(known.empty() ? "" : ", ") + demo.name;
  }
  throw std::invalid_argument("unknown demo '" + name + "' (available: " + known + ")");
}

/// Every fabric patch (or the isotropic fabric) gets mean diffusivity
/// trace / 2 = `diffusivity` (m²/s), as the scene key fabric.patches[].diffusivity.
void overrideDiffusivity(engine::EngineDef& def, double diffusivity) {
  def.diffusivity = diffusivity;
  def.fabricPatchDiffusivities.resize(def.fabricPatches.size(), 0.0);
  for (std::size_t i = 0; i < def.fabricPatches.size(); ++i) {
    stain::FabricPatch& patch = def.fabricPatches[i];
    if (patch.pattern) {
      def.fabricPatchDiffusivities[i] = diffusivity;
    } else {
      patch.tensor *= 2.0 * diffusivity / patch.tensor.trace();
    }
  }
}

std::string frameLabel(double time) {
  char text[32];
  std::snprintf(text, sizeof text, "t = %.2f s", time);
  return text;
}

int runDemo(const DemoOptions& options) {
  const Demo& demo = findDemo(options.name);
  if (options.frames < 0 || options.stepsPerFrame < 0 || !(options.timeStep >= 0) || !(options.diffusivity >= 0))
    throw std::invalid_argument("--frames must be >= 0, --steps-per-frame, --dt and --diffusivity >= 0");
  const std::string scenePath = options.scenePath.empty()
                                    ? findAsset(std::string("assets/scenes/") + demo.sceneFile)
                                    : options.scenePath;
  engine::SceneDef scene = engine::loadScene(scenePath);
  engine::EngineDef& def = scene.engine;
  if (options.timeStep > 0) def.timeStep = options.timeStep;
  if (options.diffusivity > 0) overrideDiffusivity(def, options.diffusivity);
  if (!options.pigment.empty())
    def.colors = engine::stainColorMapping(engine::pigmentPresetFromName(options.pigment), def.colors.clothColor);
  const int stepsPerFrame = options.stepsPerFrame > 0 ? options.stepsPerFrame : scene.outputs.stepsPerFrame;
  // The contact sheet holds every frame's preview: bounded as one image is
  // (a scene's 8192 x 8192 preview over 100 frames ran out of memory after
  // the run had begun).
  const double sheetPixels = double(options.frames + 1) * scene.outputs.preview.width * scene.outputs.preview.height;
  if (sheetPixels > engine::kMaxImageSamples)
    throw std::invalid_argument("--frames " + std::to_string(options.frames) + " with the scene's " +
                                std::to_string(scene.outputs.preview.width) + " x " +
                                std::to_string(scene.outputs.preview.height) + " preview makes a contact sheet of " +
                                std::to_string(static_cast<long long>(sheetPixels)) +
                                " pixels, more than 2^26: give fewer frames or a smaller outputs.preview");

  engine::Engine e(def);
  engine::FrameWriterOptions outputs;
  outputs.directory = options.outputDirectory;
  outputs.name = scene.name;
  outputs.ply.format = scene.outputs.plyFormat;
  outputs.preview = scene.outputs.preview;
  const engine::FrameWriter writer(e, outputs);

  std::vector<engine::Image> images;
  std::vector<std::string> labels;
  nlohmann::json frames = nlohmann::json::array();
  for (int frame = 0; frame <= options.frames; ++frame) {  // frame 0: the initial state
    if (frame > 0) {
      const stain::StepReport report = e.advanceSteps(stepsPerFrame);
      if (report.status != stain::StepStatus::Ok)
        throw std::runtime_error("internal step " + std::to_string(e.stepCount() + 1) + " failed in stage '" +
                                 report.stageName() + "': " + report.message);
    }
    const std::string plyPath = writer.writePly(frame);
    images.push_back(writer.renderPreview(demo.shape));
    labels.push_back(frameLabel(e.time()));
    const stain::MassBudget b = e.statistics().massBudget;
    frames.push_back({{"time_s", e.time()}, {"free_solvent_kg", b.freeSolvent}, {"solute_kg", b.freeSolute},
                      {"ply", plyPath}});
  }
  const std::string sheetPath = (std::filesystem::path(options.outputDirectory) / (scene.name + ".png")).string();
  engine::ContactSheetOptions sheetOptions;
  sheetOptions.columns = std::min(options.frames + 1, demo.columns);
  sheetOptions.labelScale = 2;
  engine::writePng(engine::contactSheet(images, labels, sheetOptions), sheetPath);

  const engine::EngineStatistics s = e.statistics();
  const nlohmann::json summary = {
      {"demo", demo.name},
      {"scene", scenePath},
      {"mesh", scene.meshDescription},
      {"vertices", e.vertexCount()},
      {"faces", e.faces().rows()},
      {"cloth_source", engine::motionSourceName(def.source)},
      {"time_step_s", def.timeStep},
      {"steps", s.steps},
      {"steps_per_second", s.stepsPerSecond},
      {"mean_ms_per_step", meanTimesJson(s)},
      {"mass_budget_kg", engine::massBudgetJson(s.massBudget)},
      {"frames", frames},
      {"contact_sheet", sheetPath}};
  std::cout << stain::dumpJson(summary, 2) << "\n";
  std::cerr << "blot demo: wrote " << sheetPath << " and " << options.frames + 1 << " PLY frames in "
            << options.outputDirectory << "\n";
  return 0;
}

}  // namespace

void registerDemoCommand(CLI::App& app, int& exitCode) {
  auto options = std::make_shared<DemoOptions>();
  std::string names;
  for (const Demo& demo : kDemos) names += std::string(names.empty() ? "" : ", ") + demo.name;
  CLI::App* command = app.add_subcommand(
      "demo", "Run a shipped demo scene; writes PLY frames and a PNG contact sheet, prints JSON. Demos: " + names);
  command->add_option("name", options->name, "Demo name")->capture_default_str();
  command->add_option("--scene", options->scenePath, "Scene file (default: the demo's, in assets/scenes/)")
      ->transform(assetPath());
  command->add_option("--out", options->outputDirectory, "Output folder (created)")
      ->capture_default_str()
      ->check(outputFolder());
  // The old name, hidden: --out is the name every command uses.
  command->add_option("--output", options->outputDirectory, "Same as --out")->group("")->check(outputFolder());
  command->add_option("--pigment", options->pigment, "wine, coffee or ink (default: the scene's)");
  command->add_option("--frames", options->frames, "Frames after the initial one (frames 0..N are written)")
      ->capture_default_str()
      ->check(CLI::Range(0, kMaxDemoFrames));
  command->add_option("--steps-per-frame", options->stepsPerFrame, "Internal steps per frame (default: the scene's)")
      ->check(CLI::Range(0, kMaxStepsPerFrame));
  // The scene parser's plausibility limits (scene.h): a time step in
  // [kMinTimeStep, 1] s, any number at most kMaxSceneMagnitude.
  command->add_option("--dt", options->timeStep, "Internal time step, s (default: the scene's)")
      ->check(zeroOr(engine::kMinTimeStep, 1, " s"));
  command->add_option("--diffusivity", options->diffusivity,
                      "Mean diffusivity trace/2 of every fabric patch, m^2/s (default: the scene's)")
      ->check(zeroOr(1e-12, engine::kMaxSceneMagnitude, " m^2/s"));  // a scene's fabric.diffusivity range
  command->callback([options, &exitCode]() {
    try {
      exitCode = runDemo(*options);
    } catch (const std::exception& error) {
      std::cerr << "blot demo: error: " << error.what() << "\n";
      exitCode = 1;
    }
  });
}

}  // namespace blot::cli
