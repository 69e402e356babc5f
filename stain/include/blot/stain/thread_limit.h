#pragma once
/// The most OpenMP threads one stain solver runs (StainSolverDef::threads,
/// StainSolver::setThreadCount): the scene key "threads", `blot run
/// --threads`, `blot figure --threads` and blotEngine_SetThreadCount refuse
/// more, so no input starts thousands of threads.

namespace blot::stain {

inline constexpr int kMaxThreads = 1024;

}  // namespace blot::stain
