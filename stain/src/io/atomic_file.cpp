// Atomic whole-file writes for frame caches and previews.
//
// Design note: a simulation may be killed at any moment (Ctrl-C, a crash, a
// time limit), and a tool watching the output folder may read a frame while it
// is being written. Writing to a sibling temporary file and renaming it over
// the target makes the switch atomic: readers see the previous file or the
// complete new one, never a prefix. The temporary lives in the same directory
// because rename() is only atomic within one filesystem. Rejected alternative:
// writing in place after truncation (a crash leaves a half-written frame that
// looks valid up to the header). Not done: fsync before rename; it protects
// against power loss, not process death, and costs milliseconds per frame.
#include <blot/stain/io/atomic_file.h>

#include <atomic>
#include <cerrno>
#include <csignal>
#include <cstdio>
#include <cstring>
#include <stdexcept>
#include <unistd.h>

namespace blot::stain {
namespace {

std::atomic<int> gWritesBeforeKill{0};  // killInWriteForTesting: 0 = off

}  // namespace

void killInWriteForTesting(int n) { gWritesBeforeKill = n > 0 ? n : 0; }

void writeFileAtomically(const std::string& path, const void* data, std::size_t size) {
  const std::string tempPath = path + "." + std::to_string(static_cast<long>(::getpid())) + ".tmp";
  std::FILE* file = std::fopen(tempPath.c_str(), "wb");
  if (file == nullptr) {
    throw std::runtime_error(path + ": cannot write the temporary file " + tempPath + ": " +
                             std::strerror(errno));
  }
  if (gWritesBeforeKill > 0 && --gWritesBeforeKill == 0) {
    std::fwrite(data, 1, size / 2, file);
    std::fflush(file);
    ::kill(::getpid(), SIGKILL);
  }
  errno = 0;
  const std::size_t written = size == 0 ? 0 : std::fwrite(data, 1, size, file);
  int writeErrno = errno;
  // fwrite may only fill the stdio buffer: a full disk (ENOSPC) or the
  // file-size limit (EFBIG, with SIGXFSZ ignored) can surface in the flush.
  errno = 0;
  const bool flushedOk = std::fflush(file) == 0;
  if (writeErrno == 0) writeErrno = errno;
  errno = 0;
  const bool closedOk = std::fclose(file) == 0;
  if (writeErrno == 0) writeErrno = errno;
  if (written != size || !flushedOk || !closedOk) {
    std::remove(tempPath.c_str());
    throw std::runtime_error(path + ": cannot write, failed after " + std::to_string(written) + " of " +
                             std::to_string(size) + " bytes: " + (writeErrno != 0 ? std::strerror(writeErrno) : "write error"));
  }
  if (std::rename(tempPath.c_str(), path.c_str()) != 0) {
    const int renameErrno = errno;
    std::remove(tempPath.c_str());
    throw std::runtime_error(path + ": cannot write, renaming the temporary file into place failed: " +
                             std::strerror(renameErrno));
  }
}

}  // namespace blot::stain
