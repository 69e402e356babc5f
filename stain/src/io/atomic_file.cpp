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
#include <sys/stat.h>
#include <unistd.h>

#include <string>
#include <vector>

namespace blot::stain {
namespace {

std::atomic<int> gWritesBeforeKill{0};  // killInWriteForTesting: 0 = off

/// Where the bytes go: a symbolic link is written through (its final target
/// is replaced, the link kept), and anything there that is not a regular file
/// is refused. Renaming over the path itself replaced a link with a file, and
/// as root turned /dev/full into a regular file without an error.
std::string writeTarget(const std::string& path) {
  std::string target = path;
  for (int hops = 0;; ++hops) {
    struct stat info {};
    if (::lstat(target.c_str(), &info) != 0) return target;  // nothing there yet: a new file
    if (S_ISREG(info.st_mode)) return target;
    if (!S_ISLNK(info.st_mode))
      throw std::runtime_error(path + ": cannot write: it exists and is not a regular file (" +
                               (S_ISDIR(info.st_mode) ? "a directory" : S_ISFIFO(info.st_mode) ? "a named pipe"
                                                                          : "a device or socket") +
                               "); refusing to replace it");
    if (hops == 40) throw std::runtime_error(path + ": cannot write: too many levels of symbolic links");
    std::vector<char> link(static_cast<std::size_t>(info.st_size > 0 ? info.st_size : 4096) + 1);
    const ssize_t n = ::readlink(target.c_str(), link.data(), link.size() - 1);
    if (n < 0) throw std::runtime_error(path + ": cannot write: cannot read the link: " + std::strerror(errno));
    const std::string next(link.data(), static_cast<std::size_t>(n));
    const std::string::size_type slash = target.rfind('/');
    target = next.empty() || next[0] == '/' || slash == std::string::npos ? next : target.substr(0, slash + 1) + next;
  }
}

}  // namespace

void killInWriteForTesting(int n) { gWritesBeforeKill = n > 0 ? n : 0; }

void writeFileAtomically(const std::string& requested, const void* data, std::size_t size) {
  const std::string path = writeTarget(requested);
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
