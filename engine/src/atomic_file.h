#pragma once
/// Private helper shared by the PLY and PNG writers: whole-file atomic writes.
#include <cstddef>
#include <string>

namespace blot::engine::detail {

/// Writes `size` bytes to `path` so that readers only ever see the old file or
/// the complete new one: the bytes go to a temporary file in the same directory
/// (`<path>.<pid>.tmp`), which is then renamed over `path` (atomic on POSIX
/// within one filesystem). On any failure the temporary is removed and a
/// std::runtime_error names the path and the system error.
void writeFileAtomically(const std::string& path, const void* data, std::size_t size);

}  // namespace blot::engine::detail
