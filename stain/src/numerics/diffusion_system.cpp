// Assembly of the diffusion systems M + hL (refilled in place) and
// DiffusionSystems: assemble, the lazy factors, the solves (design note: stages/diffusion.cpp).
#include "numerics/diffusion_system.h"

#include <algorithm>

#include "numerics/krylov_solver.h"
#include "numerics/super_time_stepping.h"

namespace blot::stain {
using namespace diffusion_internal;
namespace {

template <typename A, typename B>
bool samePattern(const Eigen::SparseMatrix<A>& a, const Eigen::SparseMatrix<B>& b) {
  if (a.rows() != b.rows() || a.cols() != b.cols() || a.nonZeros() != b.nonZeros()) return false;
  if (!a.isCompressed() || !b.isCompressed()) return false;
  return std::equal(a.outerIndexPtr(), a.outerIndexPtr() + a.cols() + 1, b.outerIndexPtr()) &&
         std::equal(a.innerIndexPtr(), a.innerIndexPtr() + a.nonZeros(), b.innerIndexPtr());
}

// Column j of M + h L in a system with L's own pattern: h L entry by entry,
// plus the mass on the diagonal. Whether the column holds its diagonal.
template <typename Scalar>
bool fillOwnColumn(const Eigen::SparseMatrix<Scalar>& stiffness, const Vector& dualAreas, double h, int j,
                   Eigen::SparseMatrix<Scalar>& system) {
  const int* sOuter = system.outerIndexPtr();
  const int* sInner = system.innerIndexPtr();
  Scalar* sValues = system.valuePtr();
  const Scalar* lValues = stiffness.valuePtr();
  bool hasDiagonal = false;
  for (int p = sOuter[j]; p < sOuter[j + 1]; ++p) {
    Scalar value = h * lValues[p];
    if (sInner[p] == j) {
      value += Scalar(dualAreas[j]);
      hasDiagonal = true;
    }
    sValues[p] = value;
  }
  return hasDiagonal;
}

// Refills `system` = M + h L in place. `system`'s pattern must contain L's
// and the diagonal; entries of `system` that L lacks get only the mass.
// Returns false if L has an entry `system` lacks (its pattern changed).
template <typename Scalar>
bool fillSystem(const Eigen::SparseMatrix<Scalar>& stiffness, const Vector& dualAreas, double h,
                Eigen::SparseMatrix<Scalar>& system) {
  if (system.rows() != stiffness.rows() || system.cols() != stiffness.cols() || !system.isCompressed()) {
    return false;
  }
  const int n = static_cast<int>(system.cols());
  const int* sOuter = system.outerIndexPtr();
  const int* sInner = system.innerIndexPtr();
  Scalar* sValues = system.valuePtr();
  const int* lOuter = stiffness.outerIndexPtr();
  const int* lInner = stiffness.innerIndexPtr();
  const int* lNonZeros = stiffness.isCompressed() ? nullptr : stiffness.innerNonZeroPtr();
  const Scalar* lValues = stiffness.valuePtr();
  if (samePattern(stiffness, system)) {
    // The system has L's own pattern (a one-ring operator holds its
    // diagonal): the same values as the merge below, without its search.
    bool everyDiagonal = true;
    for (int j = 0; j < n; ++j) {
      const bool hasDiagonal = fillOwnColumn(stiffness, dualAreas, h, j, system);
      everyDiagonal = everyDiagonal && hasDiagonal;
    }
    return everyDiagonal;
  }
  for (int j = 0; j < n; ++j) {
    int q = lOuter[j];
    const int qEnd = lNonZeros ? lOuter[j] + lNonZeros[j] : lOuter[j + 1];
    bool hasDiagonal = false;
    for (int p = sOuter[j]; p < sOuter[j + 1]; ++p) {
      const int row = sInner[p];
      Scalar value(0);
      if (q < qEnd && lInner[q] == row) {
        value = h * lValues[q];
        ++q;
      } else if (q < qEnd && lInner[q] < row) {
        return false;  // L has an entry the system lacks.
      }
      if (row == j) {
        value += Scalar(dualAreas[j]);
        hasDiagonal = true;
      }
      sValues[p] = value;
    }
    if (q != qEnd || !hasDiagonal) return false;
  }
  return true;
}

// Builds the pattern of M + h L (L's pattern plus the diagonal) and fills it.
template <typename Scalar>
void buildSystem(const Eigen::SparseMatrix<Scalar>& stiffness, const Vector& dualAreas, double h,
                 Eigen::SparseMatrix<Scalar>& system) {
  // Every column of a compressed L holding its diagonal (the one-ring
  // operators do): the union is L's own pattern, so a copy of it, without
  // the sparse sum's merge.
  bool fullDiagonal = stiffness.isCompressed() && stiffness.rows() == stiffness.cols();
  for (Eigen::Index j = 0; fullDiagonal && j < stiffness.cols(); ++j) {
    const int* begin = stiffness.innerIndexPtr() + stiffness.outerIndexPtr()[j];
    const int* end = stiffness.innerIndexPtr() + stiffness.outerIndexPtr()[j + 1];
    fullDiagonal = std::binary_search(begin, end, static_cast<int>(j));
  }
  if (fullDiagonal) {
    system = stiffness;
  } else {
    Eigen::SparseMatrix<Scalar> diagonal(stiffness.rows(), stiffness.cols());
    diagonal.setIdentity();
    system = stiffness + diagonal;  // union pattern, explicit zeros kept
    system.makeCompressed();
  }
  fillSystem(stiffness, dualAreas, h, system);
}

// Refills `system` = M + h L, building its pattern first when L has one the
// system lacks; true when it built (the analysis is then to redo).
template <typename Scalar>
bool fillOrBuildSystem(const Eigen::SparseMatrix<Scalar>& stiffness, const Vector& dualAreas, double h,
                       Eigen::SparseMatrix<Scalar>& system) {
  if (fillSystem(stiffness, dualAreas, h, system)) return false;
  buildSystem(stiffness, dualAreas, h, system);
  return true;
}

// max(0, v_0, v_1, ...) as spectralBound takes it (a NaN is skipped wherever
// it stands): the same for any order, so per-column values refreshed in part
// give the whole pass's result.
double maxFromZero(const Vector& v) {
  double m = 0.0;
  for (Eigen::Index j = 0; j < v.size(); ++j) m = std::max(m, v[j]);
  return m;
}

}  // namespace

DiffusionSystems::DiffusionSystems() = default;

void DiffusionSystems::releaseFactors() {
  scalar_.releaseFactor();
  vector_.releaseFactor();
  scalarFactorCurrent_ = vectorFactorCurrent_ = false;
  h_ = 0;  // diffuse() refuses to run until the systems are assembled again
}

void DiffusionSystems::preparePatterns(const IntrinsicGeometry& geometry) {
  const Vector& areas = geometry.vertexDualAreas;
  const auto n = areas.size();
  const auto matches = [&](const auto& stiffness) { return stiffness.rows() == n && stiffness.cols() == n; };
  // The values M + L are overwritten by the next assemble (h > 0); only the
  // patterns, and so the analysis to redo, carry over.
  if (matches(geometry.densityStiffness) && fillOrBuildSystem(geometry.densityStiffness, areas, 1.0, scalarSystem_))
    scalarReanalyze_ = vectorReanalyze_ = true;  // the vector system shares this analysis
  if (matches(geometry.velocityStiffness) && fillOrBuildSystem(geometry.velocityStiffness, areas, 1.0, vectorSystem_))
    vectorReanalyze_ = true;
  scalarInverseDiagonal_.setZero(n);  // the Jacobi diagonals assemble() writes
  vectorInverseDiagonal_.setZero(n);
  for (Vector* v : {&scalarColumnRatio_, &scalarColumnBound_, &vectorColumnRatio_, &vectorColumnBound_})
    v->setZero(n);
  filledStep_ = 0;  // values of h = 1, not of a step
}

SolverStatus DiffusionSystems::assemble(const IntrinsicGeometry& geometry, double h) {
  const Vector& areas = geometry.vertexDualAreas;
  const SparseMatrix& scalarStiffness = geometry.densityStiffness;
  const ComplexSparseMatrix& vectorStiffness = geometry.velocityStiffness;
  if (scalarStiffness.rows() != areas.size() || scalarStiffness.cols() != areas.size()) {
    return SolverStatus::SizeMismatch;
  }
  // The connection system is absent (0 x 0) when the geometry has no velocity
  // operator; then velocity diffusion reports NotAnalyzed.
  if (vectorStiffness.rows() != 0 && (vectorStiffness.rows() != areas.size() || vectorStiffness.cols() != areas.size())) {
    return SolverStatus::SizeMismatch;
  }
  h_ = h;
  ++assemblies_;
  scalarFactorCurrent_ = vectorFactorCurrent_ = false;
  if (fillOrBuildSystem(scalarStiffness, areas, h, scalarSystem_))
    scalarReanalyze_ = vectorReanalyze_ = true;  // the vector system shares this analysis
  if (vectorStiffness.rows() != 0) {
    if (fillOrBuildSystem(vectorStiffness, areas, h, vectorSystem_)) vectorReanalyze_ = true;
  } else {
    vectorSystem_.resize(0, 0);
  }
  const int n = static_cast<int>(areas.size());
  for (Vector* v : {&scalarInverseDiagonal_, &scalarColumnRatio_, &scalarColumnBound_}) v->resize(n);
  for (int j = 0; j < n; ++j) {
    scalarColumnRatio_[j] = inverseDiagonalAt(scalarSystem_, areas, j, scalarInverseDiagonal_);
    scalarColumnBound_[j] = spectralBoundTerm(scalarStiffness, areas, j);
  }
  if (vectorStiffness.rows() != 0) {
    for (Vector* v : {&vectorInverseDiagonal_, &vectorColumnRatio_, &vectorColumnBound_}) v->resize(n);
    for (int j = 0; j < n; ++j) {
      vectorColumnRatio_[j] = inverseDiagonalAt(vectorSystem_, areas, j, vectorInverseDiagonal_);
      vectorColumnBound_[j] = spectralBoundTerm(vectorStiffness, areas, j);
    }
  }
  filledStep_ = h;
  chooseMethods(h, vectorStiffness.rows() != 0);
  return SolverStatus::Ok;
}

SolverStatus DiffusionSystems::assembleColumns(const IntrinsicGeometry& geometry, double h, const int* scalarColumns,
                                               int scalarCount, const int* vectorColumns, int vectorCount) {
  const Vector& areas = geometry.vertexDualAreas;
  const SparseMatrix& scalarStiffness = geometry.densityStiffness;
  const ComplexSparseMatrix& vectorStiffness = geometry.velocityStiffness;
  const Eigen::Index n = areas.size();
  const bool columnsHold = filledStep_ == h && h > 0 && scalarColumnRatio_.size() == n &&
                           samePattern(scalarStiffness, scalarSystem_) && vectorStiffness.rows() != 0 &&
                           vectorColumnRatio_.size() == n && samePattern(vectorStiffness, vectorSystem_) &&
                           scalarStiffness.rows() == n;
  if (!columnsHold) return assemble(geometry, h);
  h_ = h;
  ++assemblies_;
  scalarFactorCurrent_ = vectorFactorCurrent_ = false;
  for (int k = 0; k < scalarCount; ++k) fillOwnColumn(scalarStiffness, areas, h, scalarColumns[k], scalarSystem_);
  for (int k = 0; k < vectorCount; ++k) fillOwnColumn(vectorStiffness, areas, h, vectorColumns[k], vectorSystem_);
  for (int k = 0; k < scalarCount; ++k) {
    const int j = scalarColumns[k];
    scalarColumnRatio_[j] = inverseDiagonalAt(scalarSystem_, areas, j, scalarInverseDiagonal_);
    scalarColumnBound_[j] = spectralBoundTerm(scalarStiffness, areas, j);
  }
  for (int k = 0; k < vectorCount; ++k) {
    const int j = vectorColumns[k];
    vectorColumnRatio_[j] = inverseDiagonalAt(vectorSystem_, areas, j, vectorInverseDiagonal_);
    vectorColumnBound_[j] = spectralBoundTerm(vectorStiffness, areas, j);
  }
  chooseMethods(h, true);
  return SolverStatus::Ok;
}

void DiffusionSystems::chooseMethods(double h, bool haveVector) {
  // Which methods may run per system (the per-solve choice among them is
  // diffuse()'s; design note).
  const bool cgForced = choice_ == DiffusionSolverChoice::Iterative;
  const bool rklForced = choice_ == DiffusionSolverChoice::SuperTimeStepping;
  const bool automatic = choice_ == DiffusionSolverChoice::Auto;
  const auto cgAllowed = [&](double ratio, double limit) { return cgForced || (automatic && ratio <= limit); };
  // Auto takes RKL2 only where it is at least as accurate as backward Euler
  // (h λ ≤ kRklAutoStepStiffness; docs/accuracy.md); forced, up to kMaxRklStages.
  const auto stages = [&](double bound) {
    if (rklForced) return rkl2Stages(h * bound);
    return automatic && h * bound <= kRklAutoStepStiffness ? rkl2Stages(h * bound) : 0;
  };
  scalarRatio_ = maxFromZero(scalarColumnRatio_);
  scalarBound_ = maxFromZero(scalarColumnBound_);
  scalarCg_ = cgAllowed(scalarRatio_, kIterativeStiffnessRatio);
  scalarStages_ = stages(scalarBound_);
  scalarIterative_ = scalarCg_ || scalarStages_ > 0;
  if (haveVector) {
    vectorRatio_ = maxFromZero(vectorColumnRatio_);
    vectorBound_ = maxFromZero(vectorColumnBound_);
    vectorCg_ = cgAllowed(vectorRatio_, kBandIterativeStiffnessRatio);
    vectorStages_ = stages(vectorBound_);
    vectorIterative_ = vectorCg_ || vectorStages_ > 0;
  } else {
    vectorBound_ = 0;
    vectorCg_ = false;
    vectorStages_ = 0;
    vectorIterative_ = false;
  }
}

SolverStatus DiffusionSystems::factorScalar() {
  if (scalarFactorCurrent_) return SolverStatus::Ok;
  if (scalarReanalyze_ || !scalar_.isAnalyzed()) {
    const SolverStatus status = scalar_.analyzePattern(scalarSystem_);
    if (status != SolverStatus::Ok) return status;
    scalarReanalyze_ = false;
  }
  ++factorizations_;
  const SolverStatus status = scalar_.factorize(scalarSystem_);
  scalarFactorCurrent_ = status == SolverStatus::Ok;
  return status;
}

SolverStatus DiffusionSystems::factorVector() {
  if (vectorFactorCurrent_) return SolverStatus::Ok;
  if (vectorSystem_.rows() == 0) return SolverStatus::NotAnalyzed;
  if (vectorReanalyze_ || !vector_.isAnalyzed()) {
    // Same pattern as the scalar system (both are P1 one-ring operators):
    // copy its ordering and symbolic factor instead of analysing again.
    SolverStatus status = SolverStatus::Ok;
    if (samePattern(vectorSystem_, scalarSystem_)) {
      if (scalarReanalyze_ || !scalar_.isAnalyzed()) {
        status = scalar_.analyzePattern(scalarSystem_);
        if (status != SolverStatus::Ok) return status;
        scalarReanalyze_ = false;
      }
      status = vector_.shareAnalysisFrom(scalar_);
    } else {
      status = vector_.analyzePattern(vectorSystem_);
    }
    if (status != SolverStatus::Ok) return status;
    vectorReanalyze_ = false;
  }
  ++factorizations_;
  const SolverStatus status = vector_.factorize(vectorSystem_);
  vectorFactorCurrent_ = status == SolverStatus::Ok;
  return status;
}

SolverStatus DiffusionSystems::factorize(const IntrinsicGeometry& geometry, double h) {
  SolverStatus status = assemble(geometry, h);
  if (status != SolverStatus::Ok) return status;
  status = factorScalar();
  const SolverStatus vectorStatus = vectorSystem_.rows() != 0 ? factorVector() : SolverStatus::Ok;
  return status != SolverStatus::Ok ? status : vectorStatus;
}

SolverStatus DiffusionSystems::solveScalar(const Vector& rhs, Vector& x) {
  const SolverStatus status = factorScalar();
  return status != SolverStatus::Ok ? status : scalar_.solve(rhs, x);
}

SolverStatus DiffusionSystems::solveScalarInPlace(Vector& a, Vector* b) {
  const SolverStatus status = factorScalar();
  if (status != SolverStatus::Ok) return status;
  return b != nullptr ? scalar_.solveInPlacePair(a, *b) : scalar_.solve(a, a);
}

SolverStatus DiffusionSystems::solveVector(const ComplexVector& rhs, ComplexVector& x) {
  const SolverStatus status = factorVector();
  return status != SolverStatus::Ok ? status : vector_.solve(rhs, x);
}

}  // namespace blot::stain
