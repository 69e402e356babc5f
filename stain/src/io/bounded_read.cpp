// Whole-file reads with a byte budget.
//
// Design note: the loaders parse from memory, so a file's size is also what
// the read allocates. A regular file is refused by its stat size before one
// byte is read; a non-regular one (a FIFO, a character device such as
// /dev/zero, a file that grows while read) has no meaningful size, so it is
// read in chunks and refused as soon as it passes the budget, or the smaller
// stream budget a caller gives (a mesh's: 64 MiB, where its file budget is
// 1 GiB), so that an endless device costs little memory before the refusal.
// A named pipe is opened without waiting for a writer (below).
#include <blot/stain/io/bounded_read.h>

#include <algorithm>
#include <cerrno>
#include <cstdio>
#include <cstring>
#include <fcntl.h>
#include <sys/stat.h>
#include <unistd.h>

namespace blot::stain {

std::string readFileBounded(const std::string& path, std::size_t maxBytes, const std::string& what,
                            std::size_t maxStreamBytes) {
  struct stat info {};
  if (::stat(path.c_str(), &info) != 0)
    throw FileReadError(path + ": cannot open " + what + ": " + std::strerror(errno));
  if (S_ISDIR(info.st_mode)) throw FileReadError(path + ": " + what + " is a directory");
  const bool regular = S_ISREG(info.st_mode);
  // A stream has no size to check first: it is read up to the stream budget.
  const std::size_t limit = regular ? maxBytes : std::min(maxBytes, maxStreamBytes);
  const auto tooLarge = [&](const std::string& size) {
    return FileReadError(path + ": " + what + " is " + size + " bytes, more than the limit of " +
                         std::to_string(limit) + " bytes");
  };
  if (regular && static_cast<unsigned long long>(info.st_size) > limit) throw tooLarge(std::to_string(info.st_size));
  // Opened without blocking, then read blocking: open() of a named pipe
  // waits for a writer, which a stray FIFO never gets (blot hung there); a
  // pipe without one reads as empty at once, one with a writer (a shell's
  // <(...)) delivers its bytes as before.
  errno = 0;
  const int descriptor = ::open(path.c_str(), O_RDONLY | O_NONBLOCK | O_CLOEXEC);
  if (descriptor < 0) throw FileReadError(path + ": cannot open " + what + ": " + std::strerror(errno));
  const int flags = ::fcntl(descriptor, F_GETFL);
  if (flags < 0 || ::fcntl(descriptor, F_SETFL, flags & ~O_NONBLOCK) != 0) {
    const int error = errno;
    ::close(descriptor);
    throw FileReadError(path + ": cannot open " + what + ": " + std::strerror(error));
  }
  std::FILE* file = ::fdopen(descriptor, "rb");
  if (file == nullptr) {
    const int error = errno;
    ::close(descriptor);
    throw FileReadError(path + ": cannot open " + what + ": " + std::strerror(error));
  }
  std::string text;
  if (regular) text.reserve(static_cast<std::size_t>(info.st_size));
  char buffer[1 << 16];
  std::size_t n = 0;
  while ((n = std::fread(buffer, 1, sizeof buffer, file)) > 0) {
    if (n > limit - text.size()) {
      std::fclose(file);
      throw FileReadError(path + ": " + what + " has more than the limit of " + std::to_string(limit) +
                          " bytes (not a regular file: read that far, then stopped)");
    }
    text.append(buffer, n);
  }
  const bool readError = std::ferror(file) != 0;
  const int readErrno = errno;
  std::fclose(file);
  if (readError) throw FileReadError(path + ": cannot read " + what + ": " + std::strerror(readErrno));
  if (S_ISFIFO(info.st_mode) && text.empty())
    throw FileReadError(path + ": " + what + " is a named pipe with nothing written to it (no writer)");
  return text;
}

}  // namespace blot::stain
