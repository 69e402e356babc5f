// Asset lookup for the command line (assets.h).
#include "assets.h"

#include <cstdlib>
#include <filesystem>
#include <stdexcept>
#include <system_error>

namespace blot::cli {
namespace fs = std::filesystem;

std::vector<std::string> dataRoots() {
  std::vector<std::string> roots;
  if (const char* env = std::getenv("BLOT_DATA_DIR"); env != nullptr && *env != '\0') roots.emplace_back(env);
  std::error_code error;
  const fs::path executable = fs::read_symlink("/proc/self/exe", error);
  if (!error) roots.push_back((executable.parent_path().parent_path() / "share" / "blot").string());
#ifdef BLOT_SOURCE_DIR
  roots.emplace_back(BLOT_SOURCE_DIR);
#endif
  return roots;
}

namespace {

/// The first root holding `relative`, or "" (also for absolute paths and
/// paths that exist as given).
std::string lookUp(const std::string& relative) {
  const fs::path path(relative);
  std::error_code error;
  if (relative.empty() || path.is_absolute() || fs::exists(path, error)) return "";
  for (const std::string& root : dataRoots()) {
    const fs::path candidate = fs::path(root) / path;
    if (fs::exists(candidate, error)) return candidate.lexically_normal().string();
  }
  return "";
}

}  // namespace

std::string findAsset(const std::string& relative) {
  std::error_code error;
  if (fs::exists(relative, error)) return relative;
  if (std::string found = lookUp(relative); !found.empty()) return found;
  std::string searched = "the working directory";
  for (const std::string& root : dataRoots()) searched += ", " + root;
  throw std::runtime_error(relative + ": not found in " + searched +
                           " (set BLOT_DATA_DIR to the folder holding assets/; the CGAL meshes under "
                           "build/external/meshes come from scripts/setup)");
}

CLI::Validator outputFolder() {
  return CLI::Validator(
      [](std::string& value) {
        return value.empty() ? std::string("expected a folder, got an empty string") : std::string();
      },
      "FOLDER");
}

CLI::Validator assetPath() {
  return CLI::Validator(
      [](std::string& value) {
        if (std::string found = lookUp(value); !found.empty()) value = found;
        return std::string();
      },
      "", "asset path");
}

}  // namespace blot::cli
