// ThreadChoice: the per-step choice between a solver's threads and one,
// driven here by step times we make up, so every branch is checked without
// depending on the machine.
#include <blot/stain/numerics/thread_choice.h>

#include "numerics/machine_load.h"

#include <gtest/gtest.h>

#include <functional>

namespace blot::stain {
namespace {

// Steps `choice` `steps` times; a step at t threads takes time(t, step).
void run(ThreadChoice& choice, int steps, const std::function<double(int, int)>& time, int* used = nullptr) {
  for (int k = 0; k < steps; ++k) {
    const int t = choice.threads();
    if (used != nullptr) used[k] = t;
    choice.record(time(t, k));
  }
}

// Steps `choice` until its probe is over (at most kProbeSteps steps); returns the steps taken.
int probe(ThreadChoice& choice, const std::function<double(int, int)>& time) {
  int steps = 0;
  while (choice.probing()) choice.record(time(choice.threads(), steps++));
  return steps;
}

// Steps `choice` through its hold, to the next probe, checking that every step
// uses `threads`; returns the hold's length.
int holdSteps(ThreadChoice& choice, const std::function<double(int, int)>& time, int threads) {
  int held = 0;
  for (; !choice.probing(); ++held) {
    EXPECT_EQ(choice.threads(), threads) << "hold step " << held;
    choice.record(time(choice.threads(), held));
  }
  return held;
}

TEST(ThreadChoice, OneThreadIsNeverProbed) {
  ThreadChoice choice(1);
  EXPECT_FALSE(choice.probing());
  for (int k = 0; k < 100; ++k) {
    EXPECT_EQ(choice.threads(), 1);
    choice.record(k % 2 ? 1.0 : 100.0);
  }
  choice.reset(0);  // counts below one mean one
  EXPECT_EQ(choice.most(), 1);
  EXPECT_EQ(choice.threads(), 1);
}

TEST(ThreadChoice, TheProbeAlternatesBothCountsStartingWithAll) {
  ThreadChoice choice(4);
  int used[ThreadChoice::kProbeSteps];
  run(choice, ThreadChoice::kProbeSteps, [](int t, int) { return t == 4 ? 1.0 : 2.0; }, used);
  for (int k = 0; k < ThreadChoice::kProbeSteps; ++k) EXPECT_EQ(used[k], k % 2 == 0 ? 4 : 1) << k;
  EXPECT_FALSE(choice.probing());
  // A first win of all threads is provisional: one thread holds until the
  // next probe confirms it (BackToAllThreadsTakesTwoProbesInARow).
  EXPECT_EQ(choice.threads(), 1);
  const auto time = [](int t, int) { return t == 4 ? 1.0 : 2.0; };
  EXPECT_EQ(holdSteps(choice, time, 1), ThreadChoice::kFirstHold);
  EXPECT_EQ(probe(choice, time), ThreadChoice::kProbeSteps);
  EXPECT_EQ(choice.threads(), 4);
}

TEST(ThreadChoice, FasterThreadsAreKeptForTheHold) {
  ThreadChoice choice(2);
  const auto time = [](int t, int) { return t == 2 ? 6.0 : 10.0; };
  run(choice, ThreadChoice::kProbeSteps, time);
  EXPECT_EQ(holdSteps(choice, time, 1), ThreadChoice::kFirstHold);  // the first win is provisional
  probe(choice, time);
  EXPECT_EQ(holdSteps(choice, time, 2), ThreadChoice::kFirstHold);  // then a probe again
}

TEST(ThreadChoice, SlowerThreadsAreDropped) {
  // Two threads 1.5x slower: the whole probe runs, and one thread wins.
  ThreadChoice choice(2);
  const auto time = [](int t, int) { return t == 2 ? 1.5 : 1.0; };
  EXPECT_EQ(probe(choice, time), ThreadChoice::kProbeSteps);
  EXPECT_EQ(choice.threads(), 1);
  EXPECT_EQ(holdSteps(choice, time, 1), ThreadChoice::kFirstHold);
}

TEST(ThreadChoice, FarSlowerThreadsEndTheFirstProbeAfterTwoPairs) {
  // A busy machine: the second thread waits for a core (15 ms against 0.2 ms
  // with one thread), so the probe stops after its second pair (the first
  // pair of the first probe never ends it: a solver's first step is also its
  // most expensive).
  ThreadChoice choice(2);
  const auto time = [](int t, int) { return t == 2 ? 15.0 : 0.2; };
  EXPECT_EQ(probe(choice, time), 4);
  EXPECT_EQ(choice.threads(), 1);
  EXPECT_EQ(holdSteps(choice, time, 1), ThreadChoice::kFirstHold);
}

TEST(ThreadChoice, ASpeedUpWithinTheMarginIsNotWorthACore) {
  ThreadChoice choice(2);
  run(choice, ThreadChoice::kProbeSteps, [](int t, int) { return t == 2 ? 0.97 : 1.0; });
  EXPECT_EQ(choice.threads(), 1);
  choice.reset(2);
  // Two probes: the first win of all threads is provisional.
  run(choice, 2 * ThreadChoice::kProbeSteps + ThreadChoice::kFirstHold, [](int t, int) { return t == 2 ? 0.94 : 1.0; });
  EXPECT_EQ(choice.threads(), 2);
}

TEST(ThreadChoice, OneSpikeDoesNotDecide) {
  // The first step at two threads pays a factorization (20x); its other
  // probe steps are faster than one thread's.
  ThreadChoice choice(2);
  run(choice, ThreadChoice::kProbeSteps, [](int t, int k) { return k == 0 ? 20.0 : (t == 2 ? 0.6 : 1.0); });
  EXPECT_EQ(choice.threads(), 1);  // two threads won, provisionally
  run(choice, ThreadChoice::kFirstHold + ThreadChoice::kProbeSteps, [](int t, int) { return t == 2 ? 0.6 : 1.0; });
  EXPECT_EQ(choice.threads(), 2);
}

TEST(ThreadChoice, OneLuckyStepDoesNotDecide) {
  // A busy machine: two threads are 3x slower except on the one step where
  // the other work left both cores free. The fastest step would pick them.
  ThreadChoice choice(2);
  run(choice, ThreadChoice::kProbeSteps, [](int t, int k) { return t == 2 ? (k == 2 ? 0.5 : 3.0) : 1.0; });
  EXPECT_EQ(choice.threads(), 1);
}

TEST(ThreadChoice, TheMedianOfEachCountDecides) {
  // Two threads: 0.7, 0.8, 2.0, 3.0 (median 1.4); one: 1.0, 1.1, 1.2, 1.3
  // (median 1.15). The means (1.625 against 1.15) agree here; the fastest
  // steps (0.7 against 1.0) do not.
  ThreadChoice choice(2);
  const double most[] = {0.7, 2.0, 0.8, 3.0}, one[] = {1.0, 1.3, 1.1, 1.2};
  run(choice, ThreadChoice::kProbeSteps, [&](int t, int k) { return t == 2 ? most[k / 2] : one[k / 2]; });
  EXPECT_EQ(choice.threads(), 1);
  // And the other way: one thread's median 1.15, two threads' 0.75 (0.5, 0.7, 0.8, 5.0).
  const double faster[] = {5.0, 0.5, 0.8, 0.7};  // the slow one first: a first probe's first pair never ends it
  choice.reset(2);
  run(choice, ThreadChoice::kProbeSteps, [&](int t, int k) { return t == 2 ? faster[k / 2] : one[k / 2]; });
  EXPECT_EQ(choice.threads(), 1);  // two threads won, provisionally; a second probe confirms
  run(choice, ThreadChoice::kFirstHold + ThreadChoice::kProbeSteps, [](int t, int) { return t == 2 ? 0.75 : 1.15; });
  EXPECT_EQ(choice.threads(), 2);
}

TEST(ThreadChoice, ALuckyFirstProbeDoesNotHoldAllThreads) {
  // Both cores busy with other work: two threads are 10x slower, except in
  // the first probe, whose steps at two threads all found the cores free.
  // Its win is provisional, and the next probe ends after one step at two.
  ThreadChoice choice(2);
  int atAll = 0;
  for (int k = 0; k < 200; ++k) {
    const int t = choice.threads();
    atAll += t == 2 ? 1 : 0;
    choice.record(t == 2 ? (k < ThreadChoice::kProbeSteps ? 0.5 : 10.0) : 1.0);
  }
  // The first probe's four steps, then one per later probe (steps ~40 and ~105).
  EXPECT_EQ(atAll, ThreadChoice::kProbeSteps / 2 + 2);
}

TEST(ThreadChoice, BackToAllThreadsTakesTwoProbesInARow) {
  ThreadChoice choice(2);
  bool busy = true;
  const auto time = [&](int t, int) { return t == 2 ? (busy ? 1.5 : 0.5) : 1.0; };
  const auto hold = [&] { return holdSteps(choice, time, choice.threads()); };
  probe(choice, time);
  EXPECT_EQ(choice.threads(), 1);
  EXPECT_EQ(hold(), ThreadChoice::kFirstHold);
  // One probe where two threads look faster (a lucky probe, or the load
  // went): still one thread, for a first hold only.
  busy = false;
  probe(choice, time);
  EXPECT_EQ(choice.threads(), 1);
  EXPECT_EQ(hold(), ThreadChoice::kFirstHold);
  // The next probe agrees: two threads.
  probe(choice, time);
  EXPECT_EQ(choice.threads(), 2);
  EXPECT_EQ(hold(), ThreadChoice::kFirstHold);
  // A lucky probe between two that pick one thread changes nothing, and the
  // hold at one thread starts over at kFirstHold.
  busy = true;
  probe(choice, time);
  EXPECT_EQ(choice.threads(), 1);
  EXPECT_EQ(hold(), ThreadChoice::kFirstHold);
  busy = false;
  probe(choice, time);
  EXPECT_EQ(choice.threads(), 1);
  busy = true;
  EXPECT_EQ(hold(), ThreadChoice::kFirstHold);
  probe(choice, time);
  EXPECT_EQ(choice.threads(), 1);
  EXPECT_EQ(hold(), 2 * ThreadChoice::kFirstHold);  // one thread won again: the hold doubles
}

TEST(ThreadChoice, TheHoldDoublesWhileTheWinnerStaysAndFallsBackWhenItChanges) {
  ThreadChoice choice(2);
  bool busy = false;
  const auto time = [&](int t, int) { return t == 2 ? (busy ? 3.0 : 0.5) : 1.0; };
  int hold = ThreadChoice::kFirstHold;
  probe(choice, time);
  EXPECT_EQ(holdSteps(choice, time, 1), ThreadChoice::kFirstHold);  // the first win is provisional
  probe(choice, time);
  for (int round = 0; round < 8; ++round) {
    EXPECT_EQ(holdSteps(choice, time, 2), hold) << round;
    EXPECT_EQ(probe(choice, time), ThreadChoice::kProbeSteps);
    hold = std::min(2 * hold, ThreadChoice::kLongestHold);
  }
  EXPECT_EQ(hold, ThreadChoice::kLongestHold);
  // The machine gets busy: the next probe picks one thread, for a first hold.
  busy = true;
  EXPECT_EQ(holdSteps(choice, time, 2), ThreadChoice::kLongestHold);
  EXPECT_EQ(probe(choice, time), 2);  // 3x slower: the first pair of a later probe ends it
  EXPECT_EQ(choice.threads(), 1);
  EXPECT_EQ(holdSteps(choice, time, 1), ThreadChoice::kFirstHold);
}

TEST(ThreadChoice, ALaterProbeOnABusyMachineCostsOneStepAtAllThreads) {
  // After the first probe every probe may end after its first pair: on a
  // busy machine each one then runs a single step at all threads, while the
  // holds at one thread double.
  ThreadChoice choice(2);
  const auto time = [](int t, int) { return t == 2 ? 15.0 : 0.2; };
  EXPECT_EQ(probe(choice, time), 4);  // the first probe: its first pair never ends it
  int hold = ThreadChoice::kFirstHold;
  for (int round = 0; round < 7; ++round) {
    EXPECT_EQ(holdSteps(choice, time, 1), hold) << round;
    int used[2];
    run(choice, 2, time, used);  // the probe: one step at two threads, one at one
    EXPECT_EQ(used[0], 2) << round;
    EXPECT_EQ(used[1], 1) << round;
    EXPECT_FALSE(choice.probing()) << round;
    EXPECT_EQ(choice.threads(), 1) << round;
    hold = std::min(2 * hold, ThreadChoice::kLongestHold);
  }
  EXPECT_EQ(hold, ThreadChoice::kLongestHold);
  // A reset starts over: its first pair does not end the probe.
  choice.reset(2);
  EXPECT_EQ(probe(choice, time), 4);
}

TEST(ThreadChoice, ProbesSkippedForWantOfIdleCoresHoldOneThread) {
  // Two threads would be faster if they ran, but the machine has no idle
  // core: every later probe is skipped, one thread holds on, and the hold
  // doubles as if one thread had won. The first probe always runs.
  ThreadChoice choice(2);
  const auto time = [](int t, int) { return t == 2 ? 0.5 : 1.0; };
  EXPECT_FALSE(choice.laterProbeStarting());
  choice.skipProbe();  // ignored: the first probe runs
  EXPECT_EQ(choice.threads(), 2);
  EXPECT_EQ(probe(choice, time), ThreadChoice::kProbeSteps);
  EXPECT_EQ(choice.threads(), 1);  // a provisional win
  int hold = ThreadChoice::kFirstHold;
  for (int round = 0; round < 7; ++round) {
    EXPECT_EQ(holdSteps(choice, time, 1), hold) << round;
    EXPECT_TRUE(choice.laterProbeStarting());
    choice.skipProbe();
    EXPECT_FALSE(choice.probing());
    EXPECT_EQ(choice.threads(), 1);
    hold = std::min(2 * hold, ThreadChoice::kLongestHold);
  }
  // Cores free again: the next probe runs and confirms two threads (the
  // provisional win was forgotten by the skipped probes, so it takes two).
  holdSteps(choice, time, 1);
  EXPECT_EQ(probe(choice, time), ThreadChoice::kProbeSteps);
  EXPECT_EQ(choice.threads(), 1);
  holdSteps(choice, time, 1);
  probe(choice, time);
  EXPECT_EQ(choice.threads(), 2);
  // Mid-probe a skip is ignored.
  holdSteps(choice, time, 2);
  choice.record(time(choice.threads(), 0));
  ASSERT_TRUE(choice.probing());
  choice.skipProbe();
  EXPECT_TRUE(choice.probing());
}

TEST(MachineLoad, RunnableTasksCountTheCallerAndBoundTheRoom) {
  const int runnable = runnableTasks();
#ifdef __linux__
  EXPECT_GE(runnable, 1);  // this test is running
  EXPECT_FALSE(roomForThreads(2, 1));  // one core cannot hold the caller and another thread
#else
  EXPECT_EQ(runnable, -1);
#endif
  EXPECT_TRUE(roomForThreads(2, 1 << 20));
  EXPECT_TRUE(roomForThreads(1, 1 << 20));
}

}  // namespace
}  // namespace blot::stain
