#pragma once
/// Rotation fits: the rotation U that best takes a vertex's rest one-ring
/// edges onto its current ones (paper sec. 3.1), by SVD (Kabsch) or by
/// Newton's method on SO(3) with the SVD as fallback.
#include <blot/stain/types.h>

#include <vector>

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

/// One vertex's rotation fit in a batch (fitRotations): what the fit reads,
/// the sums over the vertex's one-ring at one time slot, and where its values
/// go.
struct RotationFitJob {
  int vertex = 0;            ///< its id: restFrames[vertex] is read, row `vertex` of *normals written
  Matrix3 covariance;        ///< Σ_j (p_j − p_i)(p̄_j − p̄_i)ᵀ over the ring (m²)
  Vector3 normal;            ///< Σ of the ring's face cross products (unnormalised, m²)
  double normalSquared = 0;  ///< |normal|²
  Vector3 edge;              ///< to the first ring neighbour (m)
  Eigen::Quaterniond* rotation = nullptr;  ///< out: U as a unit quaternion
  Matrix3* frame = nullptr;                ///< out: the frame U F̄
  RowVectors3* normals = nullptr;          ///< out: row `vertex`, normal / |normal| (the frame's z where it is 0)
  Matrix3* fit = nullptr;                  ///< out: U
};

/// Fits jobs[0, count): U from each job's covariance by `method`
/// (WarmStartedNewton: Newton from the rotation of the rest frame F̄ =
/// restFrames[vertex] onto the frame of the job's normal and edge, four fits
/// at a time in SIMD lanes, the SVD where Newton fails; Svd: the SVD), then
/// writes U, the frame U F̄ and the unit normal through the job's pointers.
/// Adds to `counts` the fits, Newton iterations and SVD fallbacks. A job's
/// values depend on its own inputs only (not on its lane, its companions or
/// the batch). restFrames: #V 3x3 frames. Allocates nothing.
void fitRotations(RotationFitJob* jobs, int count, const std::vector<Matrix3>& restFrames, RotationFitMethod method,
                  RotationFitStats& counts);

}  // namespace blot::stain
