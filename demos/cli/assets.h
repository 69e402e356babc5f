#pragma once
/// Where `blot` finds the files it ships with (scenes, weave patterns, the CGAL
/// sample meshes), from any working directory. A relative path is looked up,
/// in order, under:
///   1. the working directory (a path that exists as given is used as given);
///   2. $BLOT_DATA_DIR, when set;
///   3. the install's share folder, <executable>/../share/blot
///      (cmake --install puts assets/ and build/external/meshes/ there);
///   4. the source tree the executable was built from (build trees).
/// So `blot figure fig5` and `blot run assets/scenes/two_way_flag.json` work
/// from anywhere, and a path the user gives that exists is never redirected.
#include <CLI/CLI.hpp>

#include <string>
#include <vector>

namespace blot::cli {

/// The folders searched after the working directory, in order.
std::vector<std::string> dataRoots();
/// `relative` resolved as above; throws std::runtime_error naming the path and
/// every folder searched when it is nowhere.
std::string findAsset(const std::string& relative);
/// For CLI11 options: rewrites a relative path that does not exist as given to
/// the first data root holding it, and leaves everything else alone (the
/// loader then reports a missing file by the name the user typed).
CLI::Validator assetPath();
/// For every command's --out: refuses an empty string, which would otherwise
/// mean the command's default folder without a word.
CLI::Validator outputFolder();

}  // namespace blot::cli
