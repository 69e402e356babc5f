#pragma once
/// Stage "diffuse" (paper sec. 3.2): implicit (backward Euler) diffusion of
/// free solvent and solute, (M + h L_Sf) σ^{t+h} = M σ^t, and of the velocity
/// with the connection Laplacian, (M + h L_Sv) u^{t+h} = M u^t; followed by a
/// mass-conserving positivity limiter (strong anisotropy breaks the M-matrix
/// property, so the solve can produce small negative densities).
#include <blot/stain/numerics/sparse_solver.h>
#include <blot/stain/stain_state.h>
#include <blot/stain/step_context.h>
#include <blot/stain/geometry/surface_geometry.h>

#include <vector>

namespace blot::stain {

/// How a diffusion system is solved. Auto (the default) picks per system at
/// factorize() from its conditioning: Jacobi-preconditioned conjugate
/// gradients restricted to the liquid when max_i h L_ii / A_i is at most
/// kIterativeStiffnessRatio (the Jacobi-scaled system then has a condition
/// number below ~2(1 + ratio) and converges in a few iterations), the direct
/// factorization otherwise. Direct and Iterative force one method (tests,
/// benchmarks); Iterative still falls back to the factor when CG stalls.
enum class DiffusionSolverChoice { Auto, Direct, Iterative };

/// The method one system used on the last solve.
enum class DiffusionMethod { None, Direct, ConjugateGradient };

/// Largest max_i h L_ii / A_i for which Auto chooses conjugate gradients.
inline constexpr double kIterativeStiffnessRatio = 4.0;
/// CG stops when ‖r‖₂ ≤ kIterativeTolerance ‖M σ‖₂ (each field); the mass
/// error this leaves (|1ᵀr|) is removed by the documented rescale, and density
/// values below kIterativeTolerance × max |σ| (inside the iterate's own error)
/// are flushed to zero before it, so the support does not creep outwards.
inline constexpr double kIterativeTolerance = 1e-9;
/// CG iterations before the solve falls back to the factorization.
inline constexpr int kMaxIterations = 60;
/// The CG's row loops (product, updates, dot products) work in chunks of this
/// many active rows, fixed whatever the thread count; each chunk's partial
/// sums are added in chunk order, so 1 and N threads give the same bits.
inline constexpr int kKrylovChunkRows = 1024;
/// Active rows from which those chunks run on OpenMP threads (below, one
/// thread does them in the same order: three fork/joins per iteration cost
/// more than the loops; measured in docs/performance.md, "Threads").
inline constexpr int kKrylovParallelRows = 16384;
/// Partial sums stored per chunk (DiffusionScratch::krylovPartials).
inline constexpr int kKrylovPartialsPerChunk = 10;

/// The factorized systems. Built once (symbolic analysis on the pattern), and
/// refactorized numerically when h or the intrinsic geometry changes.
class DiffusionSystems {
 public:
  DiffusionSystems();
  /// (Re)factorizes M + h L for both systems. The first call analyses the
  /// pattern; later calls reuse it. Returns the first failing status. Also
  /// stores the inverse diagonals (Jacobi preconditioner) and chooses each
  /// system's method (setSolverChoice).
  SolverStatus factorize(const IntrinsicGeometry& geometry, double h);
  /// Frees both numeric factors (keeping the symbolic analysis and the
  /// systems) until the next factorize(): call before an intrinsic rebuild, so
  /// the stale factors (~120 MB at 140K vertices) are not alive while the new
  /// operators are assembled. factorizedStep() is 0 until then.
  void releaseFactors();
  double factorizedStep() const { return h_; }
  int factorizationCount() const { return factorizations_; }
  const RealCholeskySolver& scalarSolver() const { return scalar_; }
  const ComplexCholeskySolver& vectorSolver() const { return vector_; }

  /// Method policy; takes effect at the next factorize() (default Auto).
  void setSolverChoice(DiffusionSolverChoice choice) { choice_ = choice; }
  DiffusionSolverChoice solverChoice() const { return choice_; }
  /// Whether the density (scalar) / velocity (connection) system is solved by CG.
  bool scalarIterative() const { return scalarIterative_; }
  bool vectorIterative() const { return vectorIterative_; }
  /// max_i h L_ii / A_i of each system (dimensionless; ~h D / dx² × 4 on a grid).
  double scalarStiffnessRatio() const { return scalarRatio_; }
  double vectorStiffnessRatio() const { return vectorRatio_; }
  /// M + h L, both triangles (the matrices the factors were computed from).
  const SparseMatrix& scalarSystem() const { return scalarSystem_; }
  const ComplexSparseMatrix& vectorSystem() const { return vectorSystem_; }
  /// 1 / diag(M + h L), #V (the Jacobi preconditioner; the connection
  /// system's diagonal is real).
  const Vector& scalarInverseDiagonal() const { return scalarInverseDiagonal_; }
  const Vector& vectorInverseDiagonal() const { return vectorInverseDiagonal_; }

 private:
  RealCholeskySolver scalar_;
  ComplexCholeskySolver vector_;
  SparseMatrix scalarSystem_;
  ComplexSparseMatrix vectorSystem_;
  Vector scalarInverseDiagonal_, vectorInverseDiagonal_;
  double scalarRatio_ = 0, vectorRatio_ = 0;
  bool scalarIterative_ = false, vectorIterative_ = false;
  DiffusionSolverChoice choice_ = DiffusionSolverChoice::Auto;
  double h_ = 0;
  int factorizations_ = 0;
};

/// Work arrays, sized once by resize() (no allocation per step). The CG
/// vectors are zero outside the solve's active set between calls.
struct DiffusionScratch {
  Vector rhs, solution;  ///< #V
  ComplexVector complexRhs, complexSolution;  ///< #V
  /// CG vectors, two numbers per vertex (solvent and solute of vertex i at
  /// 2i and 2i + 1 for the densities, Re u_i and Im u_i for the velocity, so
  /// one pass over a matrix column serves both): iterate, residual, search
  /// direction, A times direction; 2 #V each.
  Vector densityX, densityR, densityP, densityQ, velocityX, velocityR, velocityP, velocityQ;
  /// Active vertices of the density / velocity solve (breadth-first, #V
  /// capacity) and their membership marks (#V, 0 between calls).
  std::vector<int> densityActive, velocityActive;
  std::vector<char> densityMarks, velocityMarks;
  /// Per-chunk partial sums of the CG's reductions (kKrylovPartialsPerChunk
  /// per kKrylovChunkRows rows of #V).
  std::vector<double> krylovPartials;
  int densityActiveCount = 0, velocityActiveCount = 0;
  void resize(int vertexCount);
};

struct DiffusionReport {
  SolverStatus status = SolverStatus::Ok;
  double minDensityBeforeLimiter = 0;  ///< most negative density the solve produced (kg/m²)
  int limiterCorrectedVertices = 0;
  double limiterMovedMass = 0;         ///< kg
  DiffusionMethod densityMethod = DiffusionMethod::None, velocityMethod = DiffusionMethod::None;
  int densityIterations = 0, velocityIterations = 0;  ///< CG iterations (0 for direct solves)
  int densityActiveVertices = 0, velocityActiveVertices = 0;  ///< rows the CG worked on
  int fallbacks = 0;  ///< CG solves that stalled and were redone with the factor
};

/// Solves for σ_f, σ_s (if the switches and state need it) and u. Densities are
/// left unchanged if a solve fails (the status says why).
///
/// Densities by CG (DiffusionSystems::scalarIterative): warm-started at σ^t,
/// whose support is the liquid; the Krylov iterate's support grows by one ring
/// per iteration, so iteration k works on the liquid and its k-ring halo only,
/// and the result is the CG iterate of the whole-mesh system (nothing is
/// truncated). Solvent and solute share each pass over the matrix.
/// `wet` (optional, #V, 0 = outside; StainSolver passes the liquid band less
/// its outermost ring, LiquidBand::diffusionMask): the velocity is then
/// diffused by CG only on the marked vertices, with the velocities of their
/// unmarked neighbours (the band's extended values) as fixed boundary values
/// (u matters only where there is liquid); without it the velocity solve
/// covers the mesh like the densities'. A direct velocity solve always covers
/// the mesh (the solver then extends u onto the whole mesh).
DiffusionReport diffuse(const StepContext& ctx, const IntrinsicGeometry& geometry,
                        const DiffusionSystems& systems, DiffusionScratch& scratch, StainState& state,
                        const std::vector<char>* wet = nullptr);

/// Mass-conserving positivity limiter: moves mass from neighbours into each
/// vertex with negative density until none is left below zero, along mesh
/// edges, so Σ A_i σ_i is unchanged to rounding. Returns (vertices fixed,
/// mass moved in kg). densities #V, dualAreas #V.
std::pair<int, double> limitPositivity(const SurfaceTopology& topology, const Vector& dualAreas,
                                       Vector& densities);

}  // namespace blot::stain
