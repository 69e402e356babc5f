#pragma once
// Counting allocator for one test or benchmark binary: include this header in
// exactly ONE source file of the binary. Every malloc, calloc and realloc
// (operator new and Eigen's dynamic storage both end in malloc) is counted
// while `gCountAllocations` is set, then forwarded to glibc. Used to check
// that steady-state steps allocate nothing.
#include <atomic>
#include <cstddef>

extern "C" void* __libc_malloc(size_t size);
extern "C" void* __libc_calloc(size_t count, size_t size);
extern "C" void* __libc_realloc(void* pointer, size_t size);
namespace {
std::atomic<bool> gCountAllocations{false};
std::atomic<long> gAllocations{0};
void countAllocation() {
  if (gCountAllocations.load(std::memory_order_relaxed)) gAllocations.fetch_add(1, std::memory_order_relaxed);
}
}  // namespace
extern "C" void* malloc(size_t size) {
  countAllocation();
  return __libc_malloc(size);
}
extern "C" void* calloc(size_t count, size_t size) {
  countAllocation();
  return __libc_calloc(count, size);
}
extern "C" void* realloc(void* pointer, size_t size) {
  countAllocation();
  return __libc_realloc(pointer, size);
}
