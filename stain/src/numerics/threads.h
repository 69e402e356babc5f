#pragma once
// Parallel loops that cost nothing when they run on one thread.
//
// A step must not allocate (docs/scene-format.md, "Allocation"), and an OpenMP parallel
// region that runs on one thread does: GCC 12's libgomp allocates a team for
// every region and keeps it for the next one only when it has two or more
// threads, so a region whose `if` clause is false, or any region on a
// one-thread engine, costs a memalign and a free on every call (measured:
// 1,600 to 2,600 per 24 engine steps of a 625-vertex patch before this).
// The stages therefore write each parallel loop as an orphaned worksharing
// loop, `#pragma omp for schedule(static)` inside a callable, and run it with
// runLoop: inside a parallel region when it is large enough and the calling
// thread has more than one OpenMP thread (the engine's count, which the step
// sets), called directly otherwise. Outside a parallel region an orphaned
// static loop runs every iteration on the calling thread without touching the
// heap. The static schedule hands a thread the same iterations as the
// `parallel for schedule(static)` it replaces, so results are unchanged bit
// for bit. Reductions are written out: clang refuses a reduction clause on a
// variable that the callable captured, so each thread keeps its own partial
// (initialised by lowest / highest / 0) and adds it to the shared variable in
// `#pragma omp critical(blot_threads_combine)` after the loop; max, min and
// integer sums give the same bits in any order. Only static schedules: an
// orphaned dynamic loop allocates its work share when no team exists.
#include <omp.h>

#include <limits>

namespace blot::stain::threads {

/// True when a loop with `large` set should run on the calling thread's
/// OpenMP threads: it is large enough and more than one thread is available.
inline bool worthThreads(bool large) { return large && omp_get_max_threads() > 1; }

/// Identities of a max and a min reduction over T.
template <typename T>
constexpr T lowest() {
  return std::numeric_limits<T>::has_infinity ? -std::numeric_limits<T>::infinity() : std::numeric_limits<T>::lowest();
}
template <typename T>
constexpr T highest() {
  return std::numeric_limits<T>::has_infinity ? std::numeric_limits<T>::infinity() : std::numeric_limits<T>::max();
}

/// Runs `loop()` (whose body is an orphaned `#pragma omp for
/// schedule(static)`) on the calling thread's OpenMP threads when
/// worthThreads(large), else directly on the calling thread.
template <typename Loop>
void runLoop(bool large, const Loop& loop) {
  if (worthThreads(large)) {
#pragma omp parallel
    loop();
  } else {
    loop();
  }
}

}  // namespace blot::stain::threads
