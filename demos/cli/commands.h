#pragma once
/// Subcommands of the `blot` command line. Each registers itself on the app and
/// sets `exitCode` when it runs; errors go to stderr with a non-zero exit code.
#include <CLI/CLI.hpp>

namespace blot::cli {

void registerMeshInfoCommand(CLI::App& app, int& exitCode);
void registerDemoCommand(CLI::App& app, int& exitCode);
void registerHomogenizeCommand(CLI::App& app, int& exitCode);
void registerRunCommand(CLI::App& app, int& exitCode);
void registerFigureCommand(CLI::App& app, int& exitCode);  ///< `blot figure`: multi-run paper figures (figures.cpp)

}  // namespace blot::cli
