#pragma once
// How many of a solver's threads the next step uses: all of them or one,
// whichever the last steps measured faster (docs/performance.md, "Adaptive
// threads").
//
// Two threads are not always faster. On a quiet 2-core machine they are
// (1.35-1.66x on 10K and 35K wet meshes with libgomp's default spinning
// wait), but with the passive wait every parallel region pays a wake-up and
// small wet areas run slower, and on a machine busy with other work the
// spinning second thread waits for a core (a 2K-vertex velocity advection took
// 15 ms instead of 0.2 ms). libgomp reads its wait policy once, before main,
// so the process cannot fix that itself; it can stop using the threads when
// they do not pay. Every stage gives the same bits for any thread count, so
// the choice changes the time of a step and nothing else.
//
// The choice is measured, not guessed: a probe runs kProbeSteps steps
// alternating `most` threads and one, so a slow drift of the step's cost (a
// spreading stain) touches both alike, and compares each count's median step,
// so neither a one-off spike (a rebuild, a factorization, the threads'
// start-up) nor one lucky step decides. (The fastest step would favour the
// count whose times vary most: on a busy machine that is `most`, whose steps
// are fast only when the other work happens to leave both cores free.)
// `most` wins only when its median step beats one thread's by kMargin: a
// speed-up within the noise is not worth a core the rest of the application
// could use.
//
// A probe ends early, for one thread, when a pair of its steps (`most` then
// one) shows `most` more than kGiveUp times slower: on a busy machine each
// probe step at `most` can cost several one-thread steps, and such a pair is
// evidence enough (a wrong early end costs a hold at one thread, which is
// never slower than one thread). In the first probe after a reset the first
// pair does not count for it: a solver's first step (at `most`, so that the
// threads start while allocating is allowed) also assembles and factorizes.
// Every later probe can end after its first pair, so on a busy machine a
// probe costs one step at `most` (it cost two before: over 2,048 steps that
// was most of what adaptive threads cost above one thread).
//
// Going to `most` takes two probes in a row that pick `most` (the first one
// only shortens the hold at one thread to kFirstHold), starting out as after
// a hold at one thread: on a busy machine a probe's four steps at `most` can
// all be lucky, and a hold at `most` that is slower costs far more than one
// at one thread. (With one probe deciding at the start, on the game loop's
// flag with both cores busy, a lucky first probe held two threads for 32
// steps of 4-43 ms per frame against 2-9 at one thread.) On a quiet
// machine this delays two threads by kFirstHold + kProbeSteps steps.
//
// The winner then runs for a hold of kFirstHold steps,
// doubled (to kLongestHold) each time the next probe picks it again, and back
// to kFirstHold when it does not: the machine's load changes, and a longer
// hold makes the probe's cost (its steps at the slower count) smaller.
//
// A later probe is not run when the machine has no idle core for the other
// threads (skipProbe, on the solver's reading of the runnable tasks,
// machine_load.h): one thread holds on, as if it had won. Its steps at `most`
// would have waited for cores (30-40 ms against 2 ms at one thread on the
// game loop's flag with both cores busy), which no later saving repays. The
// first probe always runs: a solver's first step starts the threads while
// allocating is allowed.
//
// Not thread-safe, no allocation; the solver calls threads() before a step
// and record() after each completed one.
#include <algorithm>

namespace blot::stain {

class ThreadChoice {
 public:
  static constexpr int kProbeSteps = 8;       ///< alternating most, 1, most, 1, ... (even)
  static constexpr int kFirstHold = 32;       ///< steps at the winner after a probe that changed it
  static constexpr int kLongestHold = 1024;   ///< the longest hold (steps)
  static constexpr double kMargin = 0.95;     ///< `most` must be at least 5 % faster than one thread
  static constexpr double kGiveUp = 2.0;      ///< a pair with `most` this much slower ends the probe

  explicit ThreadChoice(int most = 1) { reset(most); }

  /// Starts over with up to `most` threads (≥ 1), probing from the next step.
  void reset(int most) {
    most_ = std::max(1, most);
    chosen_ = 0;  // no winner yet: the first hold is kFirstHold
    mostWonLast_ = false;
    hold_ = kFirstHold;
    firstProbe_ = true;
    startProbe();
  }

  /// Threads for the coming step (1 or most).
  int threads() const { return current_; }
  int most() const { return most_; }
  /// True while the steps alternate the two counts (at most kProbeSteps).
  bool probing() const { return most_ > 1 && probed_ < kProbeSteps; }
  /// True when the coming step would start a probe other than the first.
  bool laterProbeStarting() const { return probing() && probed_ == 0 && !firstProbe_; }

  /// The machine has no idle core for the other threads: the probe about to
  /// start is not run, and one thread holds as if it had won it (the hold
  /// doubles if one thread held before). Only when laterProbeStarting().
  void skipProbe() {
    if (!laterProbeStarting()) return;
    probed_ = kProbeSteps;
    mostWonLast_ = false;
    hold_ = chosen_ == 1 ? std::min(2 * hold_, kLongestHold) : kFirstHold;
    chosen_ = current_ = 1;
    left_ = hold_;
  }

  /// The completed step took `milliseconds` at threads().
  void record(double milliseconds) {
    if (most_ == 1) return;
    if (probing()) {
      const int pair = probed_ / 2;
      (current_ == most_ ? timesMost_ : timesOne_)[pair] = milliseconds;
      const bool givenUp =
          current_ == 1 && (pair > 0 || !firstProbe_) && timesMost_[pair] > kGiveUp * timesOne_[pair];
      if (++probed_ < kProbeSteps && !givenUp) {
        current_ = current_ == most_ ? 1 : most_;
        return;
      }
      probed_ = kProbeSteps;
      firstProbe_ = false;
      int winner = !givenUp && median(timesMost_) < kMargin * median(timesOne_) ? most_ : 1;
      // No winner yet (chosen_ 0) counts as a hold at one thread.
      const bool confirmed = winner != most_ || chosen_ == most_ || mostWonLast_;
      mostWonLast_ = winner == most_;
      if (!confirmed) {  // one thread held, `most` won once: one more probe soon
        winner = 1;
        hold_ = kFirstHold;
      } else {
        hold_ = winner == chosen_ ? std::min(2 * hold_, kLongestHold) : kFirstHold;
      }
      chosen_ = current_ = winner;
      left_ = hold_;
      return;
    }
    if (--left_ <= 0) startProbe();
  }

 private:
  static constexpr int kSamples = kProbeSteps / 2;  // probe steps at each count
  static_assert(kProbeSteps % 2 == 0 && kSamples >= 1, "the probe alternates the two counts");

  /// The median of one count's probe steps (the mean of the middle two).
  static double median(const double (&times)[kSamples]) {
    double sorted[kSamples];
    std::copy(times, times + kSamples, sorted);
    std::sort(sorted, sorted + kSamples);
    return 0.5 * (sorted[(kSamples - 1) / 2] + sorted[kSamples / 2]);
  }

  void startProbe() {
    probed_ = most_ > 1 ? 0 : kProbeSteps;
    current_ = most_;
    left_ = 0;
  }

  int most_ = 1;
  int current_ = 1;
  int chosen_ = 0;     // the count of the current hold (0: none yet)
  bool mostWonLast_ = false;  // the last probe picked `most` (it may not have been confirmed)
  bool firstProbe_ = true;    // the probe under way is the first since reset (its first pair never ends it)
  int hold_ = kFirstHold;
  int left_ = 0;       // steps left in the hold
  int probed_ = 0;     // steps of the current probe so far
  double timesMost_[kSamples] = {}, timesOne_[kSamples] = {};  // this probe's step times (ms)
};

}  // namespace blot::stain
