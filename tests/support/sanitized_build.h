#pragma once
// Whether this test executable is built with AddressSanitizer (scripts/sanitize:
// ASan + UBSan, the libraries at -O1; gcc defines __SANITIZE_ADDRESS__, clang
// answers __has_feature). The sanitizers make a stain step 10 to 20 times
// slower, so the few tests that run a long simulation for its endurance (not
// for a number that depends on its length) take fewer steps there, through
// stepsForThisBuild, and say so in their comment. Every test still runs in
// that build; docs/reliability.md, "CI".

#if defined(__SANITIZE_ADDRESS__)
#define BLOT_SANITIZED_BUILD 1
#elif defined(__has_feature)
#if __has_feature(address_sanitizer)
#define BLOT_SANITIZED_BUILD 1
#endif
#endif
#ifndef BLOT_SANITIZED_BUILD
#define BLOT_SANITIZED_BUILD 0
#endif

namespace blot::test {

inline constexpr bool kSanitizedBuild = BLOT_SANITIZED_BUILD != 0;

/// `steps` in a normal build, `sanitizedSteps` in the sanitized one.
constexpr int stepsForThisBuild(int steps, int sanitizedSteps) { return kSanitizedBuild ? sanitizedSteps : steps; }

}  // namespace blot::test
