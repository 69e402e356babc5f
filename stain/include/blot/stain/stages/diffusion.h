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

/// How a diffusion system is solved. Auto (the default) chooses per solve by
/// predicted cost (docs/performance.md, "The cheapest solver"): among
/// Jacobi-preconditioned conjugate gradients on the liquid's support (only
/// while max_i h L_ii / A_i ≤ kIterativeStiffnessRatio, where the
/// Jacobi-scaled system has a condition number below ~2(1 + ratio); for the
/// velocity on the band, a fixed domain, preconditioned by symmetric
/// Gauss–Seidel, kBandIterativeStiffnessRatio), the
/// explicit RKL2 super-time-stepping on the liquid's rows (only while its
/// stage count is at most kMaxRklStages, and for Auto while h λ ≤
/// kRklAutoStepStiffness, where it is the more accurate) and the whole-mesh factorization
/// (its numeric factorization counted once per assembly, amortized over the
/// solves that reuse it). Direct, Iterative and SuperTimeStepping force one
/// method (tests, benchmarks, studies); Iterative still falls back to the
/// factor when CG stalls, SuperTimeStepping uses the factor only where the
/// stage count would pass kMaxRklStages.
enum class DiffusionSolverChoice { Auto, Direct, Iterative, SuperTimeStepping };

/// The method one system used on the last solve. SuperTimeStepping is one
/// RKL2 step (second order in time) of the same semi-discrete equation
/// M σ' = −L σ that the other two integrate by backward Euler.
enum class DiffusionMethod { None, Direct, ConjugateGradient, SuperTimeStepping };

/// Largest max_i h L_ii / A_i for which Auto chooses conjugate gradients for
/// the densities, whose support grows with the solve.
inline constexpr double kIterativeStiffnessRatio = 4.0;
/// The same for the velocity on the liquid band, a fixed domain whose rows
/// the cost model knows before the solve: CG competes there with the factor
/// (charged for the whole-mesh band it needs) by predicted cost while the
/// predicted Jacobi-PCG count (94 at this ratio; the band's Gauss–Seidel PCG
/// takes about half) stays within kMaxIterations.
/// The densities keep kIterativeStiffnessRatio: on a stiff system their
/// support grows with the iterations further than the model predicts (a 2 %
/// stain on 66K vertices at h λ = 57 grew to the whole mesh in 69
/// iterations, 2x the factor's time, where the model predicted a tenth).
inline constexpr double kBandIterativeStiffnessRatio = 150.0;
/// CG stops when ‖r‖₂ ≤ kIterativeTolerance ‖M σ‖₂ (each field); the mass
/// error this leaves (|1ᵀr|) is removed by the documented rescale, and density
/// values below kIterativeTolerance × max |σ| (inside the iterate's own error)
/// are flushed to zero before it, so the support does not creep outwards.
inline constexpr double kIterativeTolerance = 1e-9;
/// CG iterations before the solve falls back to the factorization.
inline constexpr int kMaxIterations = 100;
/// The CG's row loops (product, updates, dot products) work in chunks of this
/// many active rows, fixed whatever the thread count; each chunk's partial
/// sums are added in chunk order, so 1 and N threads give the same bits.
inline constexpr int kKrylovChunkRows = 1024;
/// Active rows from which those chunks run on OpenMP threads (below, one
/// thread does them in the same order: three fork/joins per iteration cost
/// more than the loops, measured).
inline constexpr int kKrylovParallelRows = 16384;
/// Partial sums stored per chunk (DiffusionScratch::krylovPartials).
inline constexpr int kKrylovPartialsPerChunk = 10;
/// Most RKL2 stages one step may take (s ≈ √(2 h λ_max), so h λ_max ≲ 2,000);
/// beyond, the explicit scheme is never chosen.
inline constexpr int kMaxRklStages = 64;
/// Largest h λ (λ the Gershgorin bound of λ_max(M⁻¹L)) for which Auto
/// considers RKL2 (at most 8 stages): up to it, RKL2's second-order error is
/// below backward Euler's on the exact semi-discrete solution; from
/// h λ_max ≈ 50 its weakly damped stiff modes make it the less accurate
/// (tests/stain/super_time_stepping_test.cpp, docs/accuracy.md).
inline constexpr double kRklAutoStepStiffness = 32.0;
/// Relative margin on the Gershgorin bound of λ_max(M⁻¹L) when the RKL2
/// stage count is chosen (the bound itself over-estimates λ_max; the margin
/// covers its rounding).
inline constexpr double kRklStabilityMargin = 1e-6;

/// The diffusion systems M + h L and their factors. assemble() refills the
/// systems in place (and chooses each system's method); the numeric Cholesky
/// factor of a system is computed lazily, at its first direct solve after the
/// values changed (solveScalar / solveVector), so a step whose solves all run
/// by CG factorizes nothing. The symbolic analysis is done at the first
/// factorization and kept while the pattern stays the same.
class DiffusionSystems {
 public:
  DiffusionSystems();
  /// Refills M + h L for both systems, stores the inverse diagonals (Jacobi
  /// preconditioner), chooses each system's method (setSolverChoice) and marks
  /// both factors stale. Factorizes nothing. Returns SizeMismatch when the
  /// geometry's operators do not match its vertex count.
  SolverStatus assemble(const IntrinsicGeometry& geometry, double h);
  /// assemble() after a partial intrinsic refresh of the geometry the systems
  /// were last assembled from (the caller's to know), which changed the
  /// density operator only in the columns `scalarColumns` and the connection
  /// only in `vectorColumns`, and the dual areas only at vertices in both
  /// lists: refills those columns of M + h L and of the inverse diagonals,
  /// and takes the stiffness ratios and spectral bounds again as maxima over
  /// per-column values kept since (exact, in any order). The same values as
  /// assemble() gives. assemble() itself where the systems were not filled
  /// at this h or their patterns are not the operators' own.
  SolverStatus assembleColumns(const IntrinsicGeometry& geometry, double h, const int* scalarColumns,
                               int scalarCount, const int* vectorColumns, int vectorCount);
  /// Builds the systems' sparsity patterns for the geometry's operators, the
  /// part of the first assemble() that allocates, so that a solver built
  /// ahead of its steps (StainSolver's constructor) assembles its first step
  /// in place. Values stay unspecified until assemble(); nothing is analysed
  /// or factorized. A geometry whose operators do not match is left to
  /// assemble() to refuse.
  void preparePatterns(const IntrinsicGeometry& geometry);
  /// assemble() and both numeric factors now (tests, benchmarks, studies that
  /// time or inspect the factor). Returns the first failing status.
  SolverStatus factorize(const IntrinsicGeometry& geometry, double h);
  /// x = (M + h L)⁻¹ rhs for the density / connection system, factorizing it
  /// first if its values changed since its last factorization. A failed
  /// factorization is reported here (NotPositiveDefinite, NonFinite, ...) and
  /// retried at the next call.
  SolverStatus solveScalar(const Vector& rhs, Vector& x);
  /// a = A⁻¹ a, and b = A⁻¹ b when b is given, on the scalar system:
  /// bitwise what solveScalar gives each, with one pass over the factor for
  /// both (CholeskySolver::solveInPlacePair).
  SolverStatus solveScalarInPlace(Vector& a, Vector* b = nullptr);
  SolverStatus solveVector(const ComplexVector& rhs, ComplexVector& x);
  /// Frees both numeric factors (keeping the symbolic analysis and the
  /// systems) until the next assemble(): call before an intrinsic rebuild, so
  /// the stale factors (~120 MB at 140K vertices) are not alive while the new
  /// operators are assembled. assembledStep() is 0 until then.
  void releaseFactors();
  /// h the systems were assembled for (0: none, or released).
  double assembledStep() const { return h_; }
  /// Numeric factorizations done (each system's counts one) and assemblies.
  int factorizationCount() const { return factorizations_; }
  int assemblyCount() const { return assemblies_; }
  /// Whether a system's numeric factor matches its current values.
  bool scalarFactorCurrent() const { return scalarFactorCurrent_; }
  bool vectorFactorCurrent() const { return vectorFactorCurrent_; }
  const RealCholeskySolver& scalarSolver() const { return scalar_; }
  const ComplexCholeskySolver& vectorSolver() const { return vector_; }

  /// Method policy; takes effect at the next assemble() (default Auto).
  void setSolverChoice(DiffusionSolverChoice choice) { choice_ = choice; }
  DiffusionSolverChoice solverChoice() const { return choice_; }
  /// Whether a system may be solved on the liquid (by CG or RKL2) rather
  /// than by the whole-mesh factor. The densities then choose per solve by
  /// predicted cost (the factor stays a candidate); the velocity's choice
  /// between the band and the whole mesh is made here, at assemble(),
  /// because the band's extent depends on it (StainSolver reads
  /// vectorIterative()): the band whenever CG or RKL2 may run.
  bool scalarIterative() const { return scalarIterative_; }
  bool vectorIterative() const { return vectorIterative_; }
  /// Gershgorin bound of λ_max(M⁻¹L) per system (1/s; from the stiffness at assemble()).
  double scalarSpectralBound() const { return scalarBound_; }
  double vectorSpectralBound() const { return vectorBound_; }
  /// RKL2 stages one step h takes per system (0: more than kMaxRklStages, or
  /// the method is not allowed by the solver choice).
  int scalarStages() const { return scalarStages_; }
  int vectorStages() const { return vectorStages_; }
  /// Whether CG may run on a system (Auto: ratio ≤ kIterativeStiffnessRatio,
  /// for the velocity kBandIterativeStiffnessRatio).
  bool scalarCgAllowed() const { return scalarCg_; }
  bool vectorCgAllowed() const { return vectorCg_; }
  /// max_i h L_ii / A_i of each system (dimensionless; ~h D / dx² × 4 on a grid).
  double scalarStiffnessRatio() const { return scalarRatio_; }
  double vectorStiffnessRatio() const { return vectorRatio_; }
  /// M + h L, both triangles (the matrices the factors are computed from).
  const SparseMatrix& scalarSystem() const { return scalarSystem_; }
  const ComplexSparseMatrix& vectorSystem() const { return vectorSystem_; }
  /// 1 / diag(M + h L), #V (the Jacobi preconditioner; the connection
  /// system's diagonal is real).
  const Vector& scalarInverseDiagonal() const { return scalarInverseDiagonal_; }
  const Vector& vectorInverseDiagonal() const { return vectorInverseDiagonal_; }

 private:
  SolverStatus factorScalar();
  SolverStatus factorVector();
  // The maxima of the per-column values and, from them, each system's methods.
  void chooseMethods(double h, bool haveVector);

  RealCholeskySolver scalar_;
  ComplexCholeskySolver vector_;
  SparseMatrix scalarSystem_;
  ComplexSparseMatrix vectorSystem_;
  Vector scalarInverseDiagonal_, vectorInverseDiagonal_;
  double scalarRatio_ = 0, vectorRatio_ = 0;
  double scalarBound_ = 0, vectorBound_ = 0;
  // Per column: h L_jj / A_j (diag / A_j − 1) and Σ_i |L_ij| / A_j, whose
  // maxima are the ratios and bounds above; and the h the systems' values
  // were filled for (0: not filled for a step; releaseFactors keeps it).
  Vector scalarColumnRatio_, scalarColumnBound_, vectorColumnRatio_, vectorColumnBound_;
  double filledStep_ = 0;
  int scalarStages_ = 0, vectorStages_ = 0;
  bool scalarCg_ = false, vectorCg_ = false;
  bool scalarIterative_ = false, vectorIterative_ = false;
  // The factor matches the system's values; the pattern changed since the
  // last analysis (the next factorization analyses first).
  bool scalarFactorCurrent_ = false, vectorFactorCurrent_ = false;
  bool scalarReanalyze_ = true, vectorReanalyze_ = true;
  DiffusionSolverChoice choice_ = DiffusionSolverChoice::Auto;
  double h_ = 0;
  int factorizations_ = 0, assemblies_ = 0;
};

/// The rows of the connection system on a fixed domain (the velocity's band),
/// copied in the domain's order and split at the diagonal: the two triangles
/// of the symmetric Gauss–Seidel preconditioner (stages/diffusion.cpp,
/// design note). Sized by DiffusionScratch::resize.
struct DomainRows {
  std::vector<int> position;      ///< #V: a vertex's place in the domain (−1 outside, between calls)
  std::vector<int> starts;        ///< #V + 1: place k's entries begin at starts[k]
  std::vector<int> splits;        ///< #V: place k's entries below the diagonal are [starts[k], splits[k]),
                                  ///< those above [splits[k], starts[k + 1])
  std::vector<int> columns;       ///< the neighbour's place, per entry (capacity #V + 2 #E)
  std::vector<double> values;     ///< row k's entry A(k, j) as (re, im), per entry
  void resize(int vertexCount, int nonZeros);
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
  /// The direct density solve's written vertices (#V capacity): each whose
  /// solvent or solute it changed (to the bit) or left nonzero, in the order
  /// found, DiffusionReport::directSupportVertices of them; with their marks
  /// (#V, 0 between calls).
  std::vector<int> directSupport;
  std::vector<char> directMarks;
  /// The velocity's band for its preconditioned CG, and one more pair
  /// vector (2 #V) for it.
  DomainRows velocityRows;
  Vector velocityT;
  /// Sizes everything for a mesh of vertexCount vertices and edgeCount edges
  /// (the systems' one-ring pattern has #V + 2 #E entries; an edgeCount
  /// below the mesh's makes the first banded velocity solve size them).
  void resize(int vertexCount, int edgeCount = 0);
};

struct DiffusionReport {
  SolverStatus status = SolverStatus::Ok;
  double minDensityBeforeLimiter = 0;  ///< most negative density the solve produced (kg/m²)
  int limiterCorrectedVertices = 0;
  double limiterMovedMass = 0;         ///< kg
  DiffusionMethod densityMethod = DiffusionMethod::None, velocityMethod = DiffusionMethod::None;
  int densityIterations = 0, velocityIterations = 0;  ///< CG iterations (0 for direct solves)
  int densityStages = 0, velocityStages = 0;  ///< RKL2 stages (0 unless SuperTimeStepping ran)
  /// The cost model's prediction for the method each system used on the
  /// support (matrix entries visited; 0 when no restricted solve was considered).
  double densityPredictedCost = 0, velocityPredictedCost = 0;
  int densityActiveVertices = 0, velocityActiveVertices = 0;  ///< rows the CG worked on
  int fallbacks = 0;  ///< CG solves that stalled and were redone with the factor
  int factorizations = 0;  ///< numeric factorizations the direct solves needed (0–2)
  /// After a direct density solve: the vertices listed in
  /// DiffusionScratch::directSupport, all it (and the limiter after it) may
  /// have changed; −1 when there was no such solve.
  int directSupportVertices = -1;
};

/// Solves for σ_f, σ_s (if the switches and state need it) and u; under
/// soluteWithSolvent σ_s is left alone (the caller has put the whole free
/// liquid in σ_f: holdLiquidForSoluteTransport), and under
/// massWeightedViscosity u is (diffuseFilmVelocity). Densities are
/// left unchanged if a solve fails (the status says why). `systems` must be
/// assembled for ctx.h (else NotFactorized); a direct solve factorizes its
/// system first if the factor is stale.
///
/// Densities by CG (DiffusionSystems::scalarIterative): warm-started at σ^t,
/// whose support is the liquid; the Krylov iterate's support grows by one ring
/// per iteration, so iteration k works on the liquid and its k-ring halo only,
/// and the result is the CG iterate of the whole-mesh system (nothing is
/// truncated). Solvent and solute share each pass over the matrix.
/// Densities by RKL2 (DiffusionMethod::SuperTimeStepping): one explicit
/// super-time-step of s stages (DiffusionSystems::scalarStages) on the
/// support, one ring more per stage: the whole-mesh RKL2 step, second order in
/// h; the mass is restored to rounding and the limiter runs as after CG.
/// Which of the two, or the factor, runs is chosen per solve (Auto: by
/// predicted cost, DiffusionSolverChoice); the velocity the same way between
/// CG and RKL2 when vectorIterative(), on the mask below.
/// `wet` (optional, #V, 0 = outside; StainSolver passes the liquid band less
/// its vertices next to the outside, LiquidBand::diffusionMask): the velocity is then
/// diffused (CG or RKL2) only on the marked vertices, with the velocities of their
/// unmarked neighbours (the band's extended values) as fixed boundary values
/// (u matters only where there is liquid); without it the velocity solve
/// covers the mesh like the densities'. A direct velocity solve always covers
/// the mesh (the solver then extends u onto the whole mesh).
/// `velocityByFactor`: the caller chose the whole-mesh factor for this
/// step's velocity although a restricted method was allowed (StainSolver,
/// when the band's solve is predicted dearer than the factor and a band over
/// the whole mesh: velocityCostOnBand, velocityCostByFactor).
DiffusionReport diffuse(const StepContext& ctx, const IntrinsicGeometry& geometry,
                        DiffusionSystems& systems, DiffusionScratch& scratch, StainState& state,
                        const std::vector<char>* wet = nullptr, bool velocityByFactor = false);

/// The cost model's prediction (matrix entries visited; docs/performance.md,
/// "The cheapest solver") for this step's velocity diffusion on `rows` band
/// rows (a fixed domain) by the cheaper of the restricted methods the systems
/// allow (CG, RKL2); infinite when neither is allowed.
double velocityCostOnBand(const DiffusionSystems& systems, int rows);
/// The same for the whole-mesh factor (one complex field), plus the work a
/// band over the whole mesh adds for its `addedBandVertices` vertices beyond
/// the restricted band (the factor reads u everywhere, so the band must
/// extend it everywhere): kBandVertexCost entries each.
double velocityCostByFactor(const DiffusionSystems& systems, int addedBandVertices);
/// What one band vertex costs a step, in the cost model's entries (its
/// geometry, the extension, and its share of the stages over the band):
/// measured on the Table 1 bunny, 37.7K vertices, whose whole-mesh band took
/// 10.9 ms a step (290 ns a vertex) while its CG solves took 0.8 ns per
/// predicted entry.
inline constexpr double kBandVertexCost = 300.0;

/// Mass-conserving positivity limiter: moves mass from neighbours into each
/// vertex with negative density until none is left below zero, along mesh
/// edges, so Σ A_i σ_i is unchanged to rounding. Returns (vertices fixed,
/// mass moved in kg). densities #V, dualAreas #V.
std::pair<int, double> limitPositivity(const SurfaceTopology& topology, const Vector& dualAreas,
                                       Vector& densities);

}  // namespace blot::stain
