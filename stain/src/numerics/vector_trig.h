// atan2, sin and cos for a handful of values at a time, through glibc's
// vector math library (libmvec).
//
// A metric rebuild takes one atan2 per face corner (its angle) and one sine
// and cosine per face corner (the connection's phases); glibc's scalar calls
// cost about 15 ns each here, with a rounding-mode guard inside, and were
// about 40 % of a whole rebuild. libmvec's kernels compute 2 (SSE) or 4 (AVX2)
// values per call, without the guard, at 2–4 ulp (glibc's stated bound;
// tests/stain/vector_trig_test.cpp measures it): a 4-lane call costs about
// what one scalar call does.
//
// The kernel is chosen once per process by the CPU (AVX2 when it has it, SSE
// otherwise; scalar libm where the build has no libmvec: not x86-64 or glibc
// older than 2.35). Every value goes through that kernel whole: a batch's
// tail is padded to a full vector, never finished by scalar calls, and each
// lane depends only on its own input. So a value's bits do not depend on the
// batch it came in, its position there, or the thread that computed it: a
// partial rebuild, a whole one and any thread count agree. Like glibc's own
// scalar functions (ifunc variants per CPU), the last bit may differ between
// CPUs.
#pragma once

#include <blot/stain/types.h>

namespace blot::stain::trig {

enum class Kernel { Scalar, Sse2, Avx2 };

/// The kernel this process uses (the best the CPU and the build allow).
Kernel activeKernel();
/// Whether `kernel` can run on this CPU and build (Scalar always can).
bool available(Kernel kernel);
const char* name(Kernel kernel);

/// out[k] = atan2(y[k], x[k]), k < count; out may be y or x.
void atan2(const double* y, const double* x, double* out, int count);
/// out[k] = (cos a[k], sin a[k]), k < count.
void unitPhases(const double* angles, Complex* out, int count);

/// One value, through the same kernel (the same bits as in a batch).
double atan2(double y, double x);
Complex unitPhase(double angle);

/// The same with a given kernel (tests and benchmarks; it must be available).
void atan2With(Kernel kernel, const double* y, const double* x, double* out, int count);
void unitPhasesWith(Kernel kernel, const double* angles, Complex* out, int count);

}  // namespace blot::stain::trig
