// `blot`: the command line for running scenes, homogenizing weave patterns and
// inspecting meshes. Each subcommand lives in cli/<name>.cpp.
#include "commands.h"
#include "suggest.h"

#include <blot/engine/version.h>

#include <cerrno>
#include <csignal>
#include <cstring>
#include <exception>
#include <iostream>

int main(int argc, char** argv) {
  // Past the file-size limit (ulimit -f) a write fails with EFBIG instead of
  // killing the process, so the atomic writers remove their temporary and the
  // command exits non-zero with the path.
  std::signal(SIGXFSZ, SIG_IGN);
  CLI::App app{"Blot: stains forming on moving, deforming cloth"};
  app.set_version_flag("--version", blot::engine::versionString());
  app.require_subcommand(1);
  int exitCode = 0;
  blot::cli::registerRunCommand(app, exitCode);
  blot::cli::registerMeshInfoCommand(app, exitCode);
  blot::cli::registerDemoCommand(app, exitCode);
  blot::cli::registerHomogenizeCommand(app, exitCode);
  blot::cli::registerFigureCommand(app, exitCode);
  blot::cli::registerSweepCommand(app, exitCode);
  try {
    app.parse(argc, argv);
  } catch (const CLI::ParseError& e) {
    const int code = app.exit(e);
    if (code != 0) {
      if (const std::string hint = blot::cli::suggestion(app, argc, argv); !hint.empty()) std::cerr << "blot: " << hint << "\n";
    }
    return code;
  } catch (const std::exception& e) {
    std::cerr << "blot: error: " << e.what() << "\n";
    return 1;
  }
  // Every command prints its JSON to standard output: a write that failed
  // there (a full disk, a closed pipe, > /dev/full) lost it with exit 0.
  std::cout.flush();
  if (!std::cout && exitCode == 0) {
    std::cerr << "blot: error: cannot write to standard output: " << std::strerror(errno != 0 ? errno : EIO) << "\n";
    return 1;
  }
  return exitCode;
}
