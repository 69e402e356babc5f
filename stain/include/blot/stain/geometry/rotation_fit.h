#pragma once
/// Rotation fits: the rotation U that best takes a vertex's rest one-ring
/// edges onto its current ones (paper sec. 3.1), by SVD (Kabsch) or by
/// Newton's method on SO(3) with the SVD as fallback.
#include <blot/stain/types.h>

namespace blot::stain {

/// How refreshExtrinsic fits the per-vertex rotations U_i.
enum class RotationFitMethod {
  WarmStartedNewton,  ///< default: Newton on SO(3) from the rotation of the vertex's normal and
                      ///< reference edge (a guess that depends on this slot's positions only), SVD fallback
  Svd                 ///< exact 3x3 SVD at every vertex (the reference; several times slower)
};

/// Counters of the rotation fits since the last refreshExtrinsic (for profiles
/// and tests): in VertexRefresh::OnDemand, the fits of the vertices prepared so far.
struct RotationFitStats {
  int fittedVertices = 0;      ///< vertices whose U_i was fitted (0 when the mesh did not move)
  long newtonIterations = 0;   ///< total Newton iterations over those vertices
  int svdFallbacks = 0;        ///< vertices where Newton did not converge and SVD decided
};

/// Best rotation (Kabsch, via SVD of the 3x3 covariance) taking the rest
/// one-ring edge vectors (v̄_j − v̄_i) onto the current ones (v_j − v_i), with
/// the reflection case handled (det = +1). restEdges, currentEdges: k by 3.
Matrix3 kabschRotation(const Eigen::Ref<const Eigen::MatrixX3d>& restEdges,
                       const Eigen::Ref<const Eigen::MatrixX3d>& currentEdges);

/// R = argmax over SO(3) of tr(Rᵀ C), C = Σ_j (v_j − v_i)(v̄_j − v̄_i)ᵀ the 3x3
/// covariance of current times rest edge vectors, through the SVD of C
/// (det-corrected). What kabschRotation computes, from the covariance.
Matrix3 rotationFromCovariance(const Matrix3& covariance);

/// Result of fitRotation.
struct RotationFit {
  Eigen::Quaterniond rotation;  ///< unit quaternion of R
  int iterations = 0;           ///< Newton iterations taken
  bool usedSvd = false;         ///< Newton did not converge (or its Hessian was not
                                ///< positive definite); rotationFromCovariance decided
};

/// The same maximiser as rotationFromCovariance, by Newton's method on SO(3)
/// started at `initialGuess` (unit quaternion): quadratic convergence, so a
/// guess within ~0.1 rad converges in 1–3 iterations to rounding; falls back to
/// the SVD when it does not converge. Allocates nothing.
RotationFit fitRotation(const Matrix3& covariance, const Eigen::Quaterniond& initialGuess);

}  // namespace blot::stain
