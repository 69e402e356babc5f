#pragma once
/// Stage "diffuse" (paper sec. 3.2): implicit (backward Euler) diffusion of
/// free solvent and solute, (M + h L_Sf) σ^{t+h} = M σ^t, and of the velocity
/// with the connection Laplacian, (M + h L_Sv) u^{t+h} = M u^t; followed by a
/// mass-conserving positivity limiter (strong anisotropy breaks the M-matrix
/// property, so the solve can produce small negative densities).
#include <blot/stain/sparse_solver.h>
#include <blot/stain/stain_state.h>
#include <blot/stain/step_context.h>
#include <blot/stain/surface_geometry.h>

namespace blot::stain {

/// The factorized systems. Built once (symbolic analysis on the pattern), and
/// refactorized numerically when h or the intrinsic geometry changes.
class DiffusionSystems {
 public:
  DiffusionSystems();
  /// (Re)factorizes M + h L for both systems. The first call analyses the
  /// pattern; later calls reuse it. Returns the first failing status.
  SolverStatus factorize(const IntrinsicGeometry& geometry, double h);
  double factorizedStep() const { return h_; }
  int factorizationCount() const { return factorizations_; }
  const RealCholeskySolver& scalarSolver() const { return scalar_; }
  const ComplexCholeskySolver& vectorSolver() const { return vector_; }

 private:
  RealCholeskySolver scalar_;
  ComplexCholeskySolver vector_;
  SparseMatrix scalarSystem_;
  ComplexSparseMatrix vectorSystem_;
  double h_ = 0;
  int factorizations_ = 0;
};

struct DiffusionScratch {
  Vector rhs, solution;  ///< #V
  ComplexVector complexRhs, complexSolution;  ///< #V
  void resize(int vertexCount);
};

struct DiffusionReport {
  SolverStatus status = SolverStatus::Ok;
  double minDensityBeforeLimiter = 0;  ///< most negative density the solve produced (kg/m²)
  int limiterCorrectedVertices = 0;
  double limiterMovedMass = 0;         ///< kg
};

/// Solves for σ_f, σ_s (if the switches and state need it) and u. Densities are
/// left unchanged if a solve fails (the status says why).
DiffusionReport diffuse(const StepContext& ctx, const IntrinsicGeometry& geometry,
                        const DiffusionSystems& systems, DiffusionScratch& scratch, StainState& state);

/// Mass-conserving positivity limiter: moves mass from neighbours into each
/// vertex with negative density until none is left below zero, along mesh
/// edges, so Σ A_i σ_i is unchanged to rounding. Returns (vertices fixed,
/// mass moved in kg). densities #V, dualAreas #V.
std::pair<int, double> limitPositivity(const SurfaceTopology& topology, const Vector& dualAreas,
                                       Vector& densities);

}  // namespace blot::stain
