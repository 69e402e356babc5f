#pragma once
// Whether the machine has idle cores now, for ThreadChoice's probes.
//
// Linux's /proc/loadavg gives, in its fourth field ("r/t"), the number r of
// tasks runnable at this instant, the caller included. With `threads`
// threads to run, the machine has room for them when r + threads − 1 does
// not exceed the online cores. Read with open/read into a stack buffer: no
// allocation (a step must not allocate). Elsewhere, or when the file cannot be
// read, the answer is "room" (the probe then measures, as before).
#include <cstdlib>
#include <fcntl.h>
#include <unistd.h>

namespace blot::stain {

/// Tasks runnable now (the caller included), or −1 when unknown.
inline int runnableTasks() {
#ifdef __linux__
  const int fd = ::open("/proc/loadavg", O_RDONLY | O_CLOEXEC);
  if (fd < 0) return -1;
  char text[128];
  const ssize_t got = ::read(fd, text, sizeof(text) - 1);
  ::close(fd);
  if (got <= 0) return -1;
  text[got] = '\0';
  // "0.52 0.58 0.59 3/467 12345": the fourth field's numerator.
  const char* p = text;
  for (int field = 0; field < 3; ++field) {
    while (*p != '\0' && *p != ' ') ++p;
    while (*p == ' ') ++p;
  }
  char* end = nullptr;
  const long runnable = std::strtol(p, &end, 10);
  return end != p && *end == '/' && runnable >= 1 && runnable < 1000000 ? static_cast<int>(runnable) : -1;
#else
  return -1;
#endif
}

/// True unless the runnable tasks leave fewer than threads − 1 of `cores` idle.
inline bool roomForThreads(int threads, int cores) {
  const int runnable = runnableTasks();
  return runnable < 0 || cores < 1 || runnable + threads - 1 <= cores;
}

}  // namespace blot::stain
