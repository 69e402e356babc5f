// `blot sweep SWEEP.json`: speed against accuracy over a grid of scene
// overrides (docs/sweeps.md). The sweep is the Python package `blot`
// (python/blot/sweeps.py, on Dask), so this command hands its arguments to the
// interpreter the bindings were built for, with the package on PYTHONPATH.
#include "commands.h"

#include <cerrno>
#include <cstdlib>
#include <cstring>
#include <filesystem>
#include <iostream>
#include <string>
#include <system_error>
#include <vector>

#include <unistd.h>

namespace blot::cli {
namespace fs = std::filesystem;

namespace {

#ifdef BLOT_PYTHON_EXECUTABLE
/// The folder that holds the package blot/: an installed blot finds it at
/// <executable>/../BLOT_INSTALL_PYTHONDIR, a build tree at BLOT_PYTHON_BUILD_DIR;
/// $BLOT_PYTHONPATH, when set, wins.
std::string packageFolder(std::vector<std::string>& searched) {
  std::vector<std::string> candidates;
  if (const char* env = std::getenv("BLOT_PYTHONPATH"); env != nullptr && *env != '\0') candidates.emplace_back(env);
  std::error_code error;
  const fs::path executable = fs::read_symlink("/proc/self/exe", error);
  if (!error) candidates.push_back((executable.parent_path().parent_path() / BLOT_INSTALL_PYTHONDIR).string());
  candidates.emplace_back(BLOT_PYTHON_BUILD_DIR);
  for (const std::string& folder : candidates) {
    searched.push_back(folder);
    if (fs::exists(fs::path(folder) / "blot" / "__init__.py", error)) return folder;
  }
  return "";
}
#endif

int runSweep(const std::vector<std::string>& args) {
#ifndef BLOT_PYTHON_EXECUTABLE
  (void)args;
  std::cerr << "blot sweep: this blot was built without the Python bindings (BLOT_BUILD_PYTHON=OFF, or pybind11-dev, "
               "python3-dev or python3-numpy missing at configure time); sweeps run in Python (docs/sweeps.md)\n";
  return 1;
#else
  std::vector<std::string> searched;
  const std::string folder = packageFolder(searched);
  if (folder.empty()) {
    std::cerr << "blot sweep: the Python package blot is in none of:";
    for (const std::string& s : searched) std::cerr << " " << s;
    std::cerr << " (build the target blot_python, or set BLOT_PYTHONPATH)\n";
    return 1;
  }
  std::string python = BLOT_PYTHON_EXECUTABLE;
  if (const char* env = std::getenv("BLOT_PYTHON"); env != nullptr && *env != '\0') python = env;
  std::string path = folder;
  if (const char* old = std::getenv("PYTHONPATH"); old != nullptr && *old != '\0') path += std::string(":") + old;
  ::setenv("PYTHONPATH", path.c_str(), 1);
  // blot.sweeps.MAIN_COMMAND.
  std::vector<std::string> argv = {python, "-c", "import sys, blot.sweeps; sys.exit(blot.sweeps.main())"};
  argv.insert(argv.end(), args.begin(), args.end());
  std::vector<char*> raw;
  for (std::string& a : argv) raw.push_back(a.data());
  raw.push_back(nullptr);
  std::cout.flush();
  ::execv(python.c_str(), raw.data());
  std::cerr << "blot sweep: could not run " << python << ": " << std::strerror(errno) << "\n";
  return 1;
#endif
}

}  // namespace

void registerSweepCommand(CLI::App& app, int& exitCode) {
  CLI::App* command = app.add_subcommand(
      "sweep", "Speed against accuracy: run a sweep file's grid of scene overrides (serial or on Dask), "
               "write a CSV table and an error-against-cost chart (docs/sweeps.md); --help lists its options");
  // Everything after `sweep` (its --help too) goes to the Python implementation.
  command->set_help_flag();
  command->allow_extras();
  command->prefix_command();
  command->callback([command, &exitCode]() { exitCode = runSweep(command->remaining()); });
}

}  // namespace blot::cli
