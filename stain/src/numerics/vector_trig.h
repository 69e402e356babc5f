// atan2, sin and cos a batch at a time, through glibc's vector math library
// (libmvec): the metric rebuild's corner angles and phases, the ring tables.
// The kernel is chosen once per process by the CPU; a value's bits do not
// depend on the batch it comes in, its place there or the thread.
//
// Design note: docs/design-notes.md, "stain/src/numerics/vector_trig.cpp".
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
