#pragma once
/// Library version, for `blot --version` and the JSON summaries.
namespace blot::engine {
/// "major.minor.patch", from the CMake project version.
const char* versionString();
}  // namespace blot::engine
