#pragma once
/// The one atomic whole-file write: mesh files, state files, frame caches,
/// previews and checkpoints all go through it.
#include <cstddef>
#include <string>

namespace blot::stain {

/// Writes `size` bytes to `path` so that readers only ever see the old file or
/// the complete new one: the bytes go to a temporary file in the same directory
/// (`<path>.<pid>.tmp`), which is then renamed over `path` (atomic on POSIX
/// within one filesystem). On any failure the temporary is removed and a
/// std::runtime_error "<path>: cannot write ...: <system error>" is thrown.
void writeFileAtomically(const std::string& path, const void* data, std::size_t size);

/// Testing only (blot run --testing-kill-in-write): the n-th call of
/// writeFileAtomically from now on (n >= 1; 0 turns it off) writes half of its
/// bytes to the temporary file, flushes them, and sends this process SIGKILL,
/// so a test can kill a run in the middle of a write without timing luck.
void killInWriteForTesting(int n);

}  // namespace blot::stain
