// `blot homogenize PATTERN.json | --preset NAME [--tolerance T] [--subdivisions K]`:
// the effective diffusion tensor of a weave pattern with two-sided bounds, as
// one JSON object on stdout.
//
// Design note: the command is a thin shell over stain/'s loadWeavePattern and
// homogenize, so the numbers a user sees are exactly the ones a scene gets.
// Output keys, in this order (docs/patterns.md): "effective" (the mean of the
// bounds), "upper", "lower", "gap" (relative, per entry / largest eigenvalue),
// "converged", "tolerance", "unknowns", "average", "reuss", "voigt" (2x2,
// row-major nested arrays, pattern units), "eigenvalues" [min, max],
// "anisotropy" (max/min eigenvalue), "principal_angle_deg" (major axis from
// the weft/x axis, counter-clockwise, in (-90, 90]), "subdivisions" (K, or the
// graded mesh's intervals per cell side), "graded_layers", "inner_radius",
// "levels", "pattern_hash" (16 hex digits of the content hash: equal for equal
// tensors, whatever the file), "pattern", "rows", "cols". One key per line,
// values compact. Bad input, and a K or tile beyond the documented limits, is
// reported on stderr naming the file or option, with exit code 1; nothing is
// printed on stdout then, so scripts never parse half a result. A result that
// did not converge is printed with "converged": false and a warning on stderr.
#include "assets.h"
#include "commands.h"

#include <blot/stain/fabric/homogenization.h>
#include <blot/stain/fabric/weave_pattern.h>
#include <blot/stain/io/strict_json.h>

#include <nlohmann/json.hpp>

#include <cstdint>
#include <cstdio>
#include <exception>
#include <iostream>
#include <memory>
#include <string>

namespace blot::cli {
namespace {

constexpr double kPi = 3.14159265358979323846;

struct HomogenizeOptions {
  std::string patternPath;
  std::string preset;
  int subdivisions = stain::kAutoSubdivisions;
  double tolerance = stain::kDefaultGapTolerance;
  bool listPresets = false;
};

using Json = nlohmann::ordered_json;

// Adding +0.0 turns a -0.0 (from inverting a diagonal tensor) into 0.0.
Json matrixJson(const stain::Matrix2& m) {
  return {{m(0, 0) + 0.0, m(0, 1) + 0.0}, {m(1, 0) + 0.0, m(1, 1) + 0.0}};
}

// One key per line, each value compact: a 2x2 tensor reads as one row.
void printObject(const Json& object) {
  std::cout << "{\n";
  size_t i = 0;
  for (const auto& [key, value] : object.items())
    std::cout << "  " << Json(key).dump() << ": " << stain::dumpJson(value) << (++i < object.size() ? ",\n" : "\n");
  std::cout << "}\n";
}

std::string hashText(std::uint64_t hash) {
  char text[17];
  std::snprintf(text, sizeof(text), "%016llx", static_cast<unsigned long long>(hash));
  return text;
}

int runHomogenize(const HomogenizeOptions& options) {
  if (options.listPresets) {
    Json presets = Json::array();
    for (const stain::WeavePreset& preset : stain::weavePresets())
      presets.push_back({{"name", preset.name}, {"description", preset.description}, {"cells", preset.cells}});
    std::cout << stain::dumpJson(presets, 2) << "\n";
    return 0;
  }
  if (options.patternPath.empty() == options.preset.empty()) {
    std::cerr << "blot homogenize: error: give a pattern file or --preset NAME (one of them)\n";
    return 2;
  }
  try {
    const stain::WeavePattern pattern = options.preset.empty() ? stain::loadWeavePattern(options.patternPath)
                                                               : stain::presetWeavePattern(options.preset);
    const long cells = static_cast<long>(pattern.rows()) * pattern.cols();
    if (options.subdivisions > stain::maxUniformSubdivisions(pattern)) {
      std::cerr << "blot homogenize: error: --subdivisions " << options.subdivisions << ": a " << pattern.rows()
                << "x" << pattern.cols() << "-cell tile needs rows*cols*K^2 = "
                << cells * options.subdivisions * options.subdivisions << " unknowns, more than the limit of "
                << stain::kMaxCellProblemUnknowns << "; the largest K for this tile is "
                << stain::maxUniformSubdivisions(pattern) << " (or leave --subdivisions out to refine until "
                << "the bounds meet)\n";
      return 1;
    }
    stain::HomogenizationOptions homogenization;
    homogenization.subdivisions = options.subdivisions;
    homogenization.tolerance = options.tolerance;
    const stain::HomogenizationResult r = stain::homogenize(pattern, homogenization);
    const Json out = {{"effective", matrixJson(r.effective)},
                      {"upper", matrixJson(r.upper)},
                      {"lower", matrixJson(r.lower)},
                      {"gap", r.gap},
                      {"converged", r.converged},
                      {"tolerance", r.tolerance},
                      {"unknowns", r.vertexCount},
                      {"average", matrixJson(r.average)},
                      {"reuss", matrixJson(r.reussBound)},
                      {"voigt", matrixJson(r.voigtBound)},
                      {"eigenvalues", {r.eigenvalues(0), r.eigenvalues(1)}},
                      {"anisotropy", r.eigenvalues(1) / r.eigenvalues(0)},
                      {"principal_angle_deg", r.principalAngle * 180.0 / kPi + 0.0},
                      {"subdivisions", r.subdivisions},
                      {"graded_layers", r.gradedLayers},
                      {"inner_radius", r.innerRadius},
                      {"levels", r.levels},
                      {"pattern_hash", hashText(r.patternHash)},
                      {"pattern", pattern.sourceName()},
                      {"rows", pattern.rows()},
                      {"cols", pattern.cols()}};
    if (!r.converged)
      std::cerr << "blot homogenize: warning: " << pattern.sourceName() << ": not converged: the bounds differ by "
                << r.gap << " of the largest eigenvalue, more than the tolerance " << r.tolerance << ", at "
                << r.vertexCount << " unknowns"
                << (options.subdivisions > 0 ? " (a fixed --subdivisions; leave it out to refine)"
                                             : " (the next refinement would exceed the limit of " +
                                                   std::to_string(stain::kMaxCellProblemUnknowns) + " unknowns)")
                << "\n";
    printObject(out);
    return 0;
  } catch (const std::exception& e) {
    std::cerr << "blot homogenize: error: " << e.what() << "\n";
    return 1;
  }
}

}  // namespace

void registerHomogenizeCommand(CLI::App& app, int& exitCode) {
  auto options = std::make_shared<HomogenizeOptions>();
  CLI::App* command = app.add_subcommand(
      "homogenize", "Print the effective (homogenized) diffusion tensor of a weave pattern as JSON "
                    "(docs/patterns.md)");
  CLI::Option* file = command->add_option("pattern", options->patternPath, "Pattern file (.json)")->transform(assetPath());
  CLI::Option* preset = command->add_option(
      "--preset", options->preset, "Use a named preset instead of a file: plain, twill-2-1, twill-3-1, "
                                   "satin-5, basket, rib-knit");
  file->excludes(preset);
  command->add_option("-k,--subdivisions", options->subdivisions,
                      "Solve once on the uniform mesh with K squares per cell side, rows*cols*K^2 <= 500000 "
                      "(default: graded meshes refined until the bounds meet, docs/patterns.md)")
      ->check(CLI::Range(1, 256));
  command->add_option("-t,--tolerance", options->tolerance,
                      "Relative gap between the upper and lower bound to reach, per entry as a fraction of the "
                      "largest eigenvalue (default 0.01)")
      ->check(CLI::Validator(
          [](std::string& text) -> std::string {
            // CLI::Range lets NaN through (no comparison fails), and calls
            // "abc" out of range: a number in the range, said so.
            std::size_t used = 0;
            double value = 0;
            try {
              value = std::stod(text, &used);
            } catch (const std::exception&) {
              used = 0;
            }
            if (used == text.size() && value >= 1e-6 && value <= 0.5) return "";
            return text + ": expected a number in [1e-06, 0.5]";
          },
          "NUMBER in [1e-06, 0.5]"));
  CLI::Option* list = command->add_flag("--list-presets", options->listPresets, "List the presets and their cells as JSON");
  list->excludes(file);  // ignored silently before
  list->excludes(preset);
  command->callback([options, &exitCode]() { exitCode = runHomogenize(*options); });
}

}  // namespace blot::cli
