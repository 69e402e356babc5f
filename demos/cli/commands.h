#pragma once
/// Subcommands of the `blot` command line. Each registers itself on the app and
/// sets `exitCode` when it runs; errors go to stderr with a non-zero exit code.
#include <blot/engine/engine.h>
#include <blot/stain/step_profile.h>

#include <CLI/CLI.hpp>
#include <nlohmann/json.hpp>

#include <array>
#include <string>

namespace blot::cli {

/// Mean milliseconds per internal step since the engine was built: the stain
/// stages ("stain_geometry", "stain_forces", "stain_advect_velocity", ...) and
/// "cloth", "stain", "coupling", "total" (engine::statisticsJson's
/// "mean_ms_per_step").
nlohmann::json meanTimesJson(const engine::EngineStatistics& statistics);

void registerMeshInfoCommand(CLI::App& app, int& exitCode);
void registerDemoCommand(CLI::App& app, int& exitCode);
void registerHomogenizeCommand(CLI::App& app, int& exitCode);
void registerRunCommand(CLI::App& app, int& exitCode);
void registerFigureCommand(CLI::App& app, int& exitCode);  ///< `blot figure`: multi-run paper figures (figures.cpp)
void registerSweepCommand(CLI::App& app, int& exitCode);   ///< `blot sweep`: runs python/blot/sweeps.py (sweep.cpp)

}  // namespace blot::cli
