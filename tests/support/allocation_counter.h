#pragma once
// Counting allocator for one test or benchmark binary: include this header in
// exactly ONE source file of the binary. Every malloc, calloc, realloc and
// aligned allocation (operator new, Eigen, CHOLMOD and OpenMP all end there) is counted
// while `gCountAllocations` is set, then forwarded to glibc. Used to check
// that steady-state steps allocate nothing.
//
// Under AddressSanitizer the replacement is left out: ASan brings its own
// malloc, and ours (forwarding to glibc's) would run before ASan starts and
// hand it memory it never allocated (a crash at start-up, in gcc and clang).
// kCountsAllocations is false then, and tests of allocation counts skip.
#include <atomic>
#include <cstddef>

#if defined(__SANITIZE_ADDRESS__)
#define BLOT_COUNTS_ALLOCATIONS 0
#elif defined(__has_feature)
#if __has_feature(address_sanitizer)
#define BLOT_COUNTS_ALLOCATIONS 0
#endif
#endif
#ifndef BLOT_COUNTS_ALLOCATIONS
#define BLOT_COUNTS_ALLOCATIONS 1
#endif

namespace {
std::atomic<bool> gCountAllocations{false};
std::atomic<long> gAllocations{0};
[[maybe_unused]] void countAllocation() {
  if (gCountAllocations.load(std::memory_order_relaxed)) gAllocations.fetch_add(1, std::memory_order_relaxed);
}
[[maybe_unused]] constexpr bool kCountsAllocations = BLOT_COUNTS_ALLOCATIONS != 0;
}  // namespace
#if BLOT_COUNTS_ALLOCATIONS
extern "C" void* __libc_malloc(size_t size);
extern "C" void* __libc_calloc(size_t count, size_t size);
extern "C" void* __libc_realloc(void* pointer, size_t size);
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
extern "C" void* __libc_memalign(size_t alignment, size_t size);
extern "C" void* aligned_alloc(size_t alignment, size_t size) {
  countAllocation();
  return __libc_memalign(alignment, size);
}
extern "C" void* memalign(size_t alignment, size_t size) {
  countAllocation();
  return __libc_memalign(alignment, size);
}
extern "C" int posix_memalign(void** pointer, size_t alignment, size_t size) {
  countAllocation();
  *pointer = __libc_memalign(alignment, size);
  return *pointer != nullptr ? 0 : 12;  // ENOMEM
}
#endif
