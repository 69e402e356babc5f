// The two-tier geometry cache: intrinsic operators rebuilt on strain, extrinsic
// frames refreshed every step (paper sec. 3.1 and 4; DESIGN.md step 2).
//
// Design note: docs/design-notes.md, "stain/src/geometry/surface_geometry.cpp".
#include <blot/stain/geometry/surface_geometry.h>

#include <blot/stain/geometry/extrinsic_geometry.h>
#include <blot/stain/geometry/intrinsic_geometry.h>
#include <blot/stain/geometry/operators.h>

#include <Eigen/SVD>

#include <algorithm>
#include <cmath>
#include <sstream>
#include <stdexcept>
#include <string>

#include "numerics/lanes.h"
#include "numerics/threads.h"

namespace blot::stain {
namespace {

// Newton accepts the current rotation when the gradient g = 2 vee(skew RᵀC) is
// below this fraction of tr(RᵀC): the step it would take is then below
// ~1e-13 rad for any ring whose Hessian is not extremely anisotropic.
constexpr double kGradientTolerance = 1e-13;
// ... and stops after a step shorter than this (rad): the error left is
// O(step²) ≈ 1e-14 (quadratic convergence), so no confirming iteration is needed.
constexpr double kNewtonStepTolerance = 1e-7;
constexpr int kMaxNewtonIterations = 8;
// Vertices prepared together (prepareGroup): their fits, up to two each,
// fill the lanes of fitSlots.
constexpr int kPrepareGroup = 4;
// A Newton step longer than this (rad) means the start was far off: use the SVD.
constexpr double kMaxNewtonStep = 1.0;
// Relative size of a Hessian pivot below which the fit is treated as degenerate.
constexpr double kPivotTolerance = 1e-10;
// Below this many vertices a refresh takes a few microseconds and waking a
// second thread costs more than it saves (and much more on a loaded machine).
constexpr int kMinParallelVertices = 2048;

// max_e |ℓ_e/ℓ̂_e − 1| from the extremes of the squared ratios ℓ_e²/ℓ̂_e²
// over the measured edges (1 and 1 for none): the strain tests' one root each.
double strainFromSquaredRatios(double maxRatio, double minRatio) {
  return std::max(std::sqrt(maxRatio) - 1.0, 1.0 - std::sqrt(minRatio));
}

// Rotation vector (axis × angle, angle in [0, π]) of a unit quaternion
// q = (cos θ/2, sin θ/2 a): θ a = v · 2 atan(x)/(x w), x = |v|/w (w ≥ 0). For
// x² < 1e-3 (θ < 0.063 rad, the usual per-step rotation) atan(x)/x is its
// series to x¹⁰, truncation x¹²/13 < 1e-19: no square root, division or atan2.
Vector3 rotationVector(const Eigen::Quaterniond& q) {
  const double sign = q.w() < 0 ? -1.0 : 1.0;
  const Vector3 v = sign * q.vec();
  const double w = sign * q.w();
  const double vv = v.squaredNorm();
  if (vv < 1e-3 * w * w) {
    const double y = vv / (w * w);
    const double atanRatio =
        1.0 - y * (1.0 / 3 - y * (1.0 / 5 - y * (1.0 / 7 - y * (1.0 / 9 - y * (1.0 / 11)))));
    return v * (2.0 * atanRatio / w);
  }
  const double s = std::sqrt(vv);
  if (s == 0.0) return Vector3::Zero();
  return v * (2.0 * std::atan2(s, w) / s);
}

// Rotation fits in lanes. The fits of a vertex list are independent chains
// of divisions and roots (~300 ns a vertex, latency-bound): kFitLanes of them
// go through each step together, so the core overlaps them, two to an SSE2
// register (numerics/lanes.h). Every lane does the same operations
// on its own values, in the same order as a lone fit would: a fit's bits do
// not depend on its lane, its companions, the list or the thread. A lane past
// the fits given repeats the first one; its results are dropped.
constexpr int kFitLanes = 4;
static_assert(kFitLanes == lanes::kLanes, "a fit per lane of numerics/lanes.h");

struct LaneQuaternions {
  double w[kFitLanes], x[kFitLanes], y[kFitLanes], z[kFitLanes];
};

// R(q) (Eigen's toRotationMatrix) of every lane, row-major: R[3r + c].
void laneRotationMatrices(const lanes::Lanes& w, const lanes::Lanes& x, const lanes::Lanes& y,
                          const lanes::Lanes& z, lanes::Lanes (&R)[9]) {
  const lanes::Lanes tx = 2.0 * x, ty = 2.0 * y, tz = 2.0 * z;
  const lanes::Lanes twx = tx * w, twy = ty * w, twz = tz * w;
  const lanes::Lanes txx = tx * x, txy = ty * x, txz = tz * x;
  const lanes::Lanes tyy = ty * y, tyz = tz * y, tzz = tz * z;
  R[0] = 1.0 - (tyy + tzz);
  R[1] = txy - twz;
  R[2] = txz + twy;
  R[3] = txy + twz;
  R[4] = 1.0 - (txx + tzz);
  R[5] = tyz - twx;
  R[6] = txz - twy;
  R[7] = tyz + twx;
  R[8] = 1.0 - (txx + tyy);
}

enum class LaneStatus : char { Active, Converged, Failed };

// The Newton iteration behind fitRotation (see the design note), in lanes.
// C: each lane's covariance; q: each lane's start, on return its rotation;
// iterations: taken. A lane whose status is Failed on return gave up (the
// caller then takes the SVD). Every lane takes every iteration (a finished
// lane's values are dropped), so the arithmetic runs on all four at once.
void newtonLanes(const Matrix3* const (&C)[kFitLanes], LaneQuaternions& q, int (&iterations)[kFitLanes],
                 LaneStatus (&status)[kFitLanes]) {
  using lanes::Lanes;
  for (int l = 0; l < kFitLanes; ++l) {
    status[l] = LaneStatus::Active;
    iterations[l] = 0;
  }
  // c[3r + k]: entry (r, k) of each lane's covariance.
  Lanes c[9];
  for (int r = 0; r < 3; ++r)
    for (int k = 0; k < 3; ++k)
      c[3 * r + k] = lanes::gather((*C[0])(r, k), (*C[1])(r, k), (*C[2])(r, k), (*C[3])(r, k));
  for (int iteration = 1; iteration <= kMaxNewtonIterations; ++iteration) {
    const Lanes qw = lanes::load(q.w), qx = lanes::load(q.x), qy = lanes::load(q.y), qz = lanes::load(q.z);
    Lanes R[9];
    laneRotationMatrices(qw, qx, qy, qz, R);
    // M = Rᵀ C.
    Lanes M[3][3];
    for (int r = 0; r < 3; ++r)
      for (int k = 0; k < 3; ++k) M[r][k] = R[r] * c[k] + R[3 + r] * c[3 + k] + R[6 + r] * c[6 + k];
    const Lanes trace = M[0][0] + M[1][1] + M[2][2];
    // g = 2 vee(skew M); the Newton step is δ = (tr M·I − sym M)⁻¹ g, by
    // unpivoted LDLᵀ (pivots checked below).
    const Lanes g0 = M[2][1] - M[1][2], g1 = M[0][2] - M[2][0], g2 = M[1][0] - M[0][1];
    const Lanes gradient = g0 * g0 + g1 * g1 + g2 * g2;
    const Lanes h00 = trace - M[0][0], h11 = trace - M[1][1], h22 = trace - M[2][2];
    const Lanes h10 = -0.5 * (M[1][0] + M[0][1]), h20 = -0.5 * (M[2][0] + M[0][2]);
    const Lanes h21 = -0.5 * (M[2][1] + M[1][2]);
    const Lanes tiny = kPivotTolerance * trace;
    const Lanes d0 = h00;
    const Lanes r0 = 1.0 / h00;
    const Lanes l10 = h10 * r0, l20 = h20 * r0;
    const Lanes d1 = h11 - l10 * h10;
    const Lanes r1 = 1.0 / d1;
    const Lanes l21 = (h21 - l20 * h10) * r1;
    const Lanes d2 = h22 - l20 * h20 - l21 * l21 * d1;
    const Lanes y0 = g0, y1 = g1 - l10 * y0, y2 = g2 - l20 * y0 - l21 * y1;
    const Lanes x2 = y2 / d2;
    const Lanes x1 = y1 * r1 - l21 * x2;
    const Lanes x0 = y0 * r0 - l10 * x1 - l20 * x2;
    const Lanes stepSquared = x0 * x0 + x1 * x1 + x2 * x2;
    // q ⊗ (1, δ/2), normalised: |(1, δ/2)| = √(1 + |δ|²/4) and |q| = 1.
    const Lanes cw = 1.0 / lanes::sqrt(1.0 + 0.25 * stepSquared);
    const Lanes hx = 0.5 * cw * x0, hy = 0.5 * cw * x1, hz = 0.5 * cw * x2;
    LaneQuaternions next;
    lanes::store(qw * cw - qx * hx - qy * hy - qz * hz, next.w);
    lanes::store(qw * hx + qx * cw + qy * hz - qz * hy, next.x);
    lanes::store(qw * hy + qy * cw + qz * hx - qx * hz, next.y);
    lanes::store(qw * hz + qz * cw + qx * hy - qy * hx, next.z);
    double traceOf[kFitLanes], gradientOf[kFitLanes], tinyOf[kFitLanes], d0Of[kFitLanes], d1Of[kFitLanes],
        d2Of[kFitLanes], stepOf[kFitLanes];
    lanes::store(trace, traceOf);
    lanes::store(gradient, gradientOf);
    lanes::store(tiny, tinyOf);
    lanes::store(d0, d0Of);
    lanes::store(d1, d1Of);
    lanes::store(d2, d2Of);
    lanes::store(stepSquared, stepOf);
    bool active = false;
    for (int l = 0; l < kFitLanes; ++l) {
      if (status[l] != LaneStatus::Active) continue;
      iterations[l] = iteration;
      if (!(traceOf[l] > 0)) {
        status[l] = LaneStatus::Failed;
      } else if (gradientOf[l] <= kGradientTolerance * kGradientTolerance * traceOf[l] * traceOf[l]) {
        status[l] = LaneStatus::Converged;
      } else if (!(d0Of[l] > tinyOf[l]) || !(d1Of[l] > tinyOf[l]) || !(d2Of[l] > tinyOf[l]) ||
                 !(stepOf[l] <= kMaxNewtonStep * kMaxNewtonStep)) {
        status[l] = LaneStatus::Failed;
      } else {
        q.w[l] = next.w[l];
        q.x[l] = next.x[l];
        q.y[l] = next.y[l];
        q.z[l] = next.z[l];
        if (stepOf[l] <= kNewtonStepTolerance * kNewtonStepTolerance) {
          status[l] = LaneStatus::Converged;
        } else {
          active = true;
        }
      }
    }
    if (!active) return;
  }
  for (int l = 0; l < kFitLanes; ++l)
    if (status[l] == LaneStatus::Active) status[l] = LaneStatus::Failed;
}

// One fit's inputs for its start: the ring's (unnormalised) normal with its
// squared length, the reference edge (to the first ring neighbour) and the
// rest frame.
struct FitInputs {
  const Vector3* normal;
  double normalSquared;
  const Vector3* edge;
  const Matrix3* restFrame;
};

// Newton's starting rotation of each lane, for a ring with normal direction
// `normal` and reference edge `edge`: the rotation taking the rest frame F̄
// (normal, edge in its tangent plane) onto the same frame built from these.
// Exact for a rigidly moved ring; off by the ring's shear otherwise (Newton
// converges in 2–4 iterations from there). A function of the slot's
// positions only, so a fit gives the same bits whichever vertices were
// fitted before. Identity where the frame is degenerate (Newton or the SVD
// then decide). Also each lane's unit normal n / |n|, the slot's normal, and
// its rest frame F̄ (entry (r, c) at [3r + c]), which the frame U F̄ reads.
void frameGuessLanes(const FitInputs (&in)[kFitLanes], LaneQuaternions& q, double (&unitNormal)[3][kFitLanes],
                     lanes::Lanes (&restFrame)[9]) {
  using lanes::Lanes;
  const auto gather = [&](const auto& entry) {
    return lanes::gather(entry(in[0]), entry(in[1]), entry(in[2]), entry(in[3]));
  };
  const Lanes nx = gather([](const FitInputs& f) { return f.normal->x(); });
  const Lanes ny = gather([](const FitInputs& f) { return f.normal->y(); });
  const Lanes nz = gather([](const FitInputs& f) { return f.normal->z(); });
  const Lanes ex = gather([](const FitInputs& f) { return f.edge->x(); });
  const Lanes ey = gather([](const FitInputs& f) { return f.edge->y(); });
  const Lanes ez = gather([](const FitInputs& f) { return f.edge->z(); });
  const Lanes inverse = 1.0 / lanes::sqrt(gather([](const FitInputs& f) { return f.normalSquared; }));
  const Lanes z0 = nx * inverse, z1 = ny * inverse, z2 = nz * inverse;
  Lanes y0 = z1 * ez - z2 * ey, y1 = z2 * ex - z0 * ez, y2 = z0 * ey - z1 * ex;
  const Lanes length = lanes::sqrt(y0 * y0 + y1 * y1 + y2 * y2);
  const Lanes edgeLength = lanes::sqrt(ex * ex + ey * ey + ez * ez);
  y0 = y0 / length;
  y1 = y1 / length;
  y2 = y2 / length;
  const Lanes x0 = y1 * z2 - y2 * z1, x1 = y2 * z0 - y0 * z2, x2 = y0 * z1 - y1 * z0;
  const Lanes frame[3][3] = {{x0, y0, z0}, {x1, y1, z1}, {x2, y2, z2}};
  // Q = frame F̄ᵀ.
  double Q[3][3][kFitLanes];
  for (int c = 0; c < 3; ++c) {
    Lanes* F = restFrame + 3 * c;  // row c of F̄
    for (int k = 0; k < 3; ++k) F[k] = gather([&](const FitInputs& f) { return (*f.restFrame)(c, k); });
    for (int r = 0; r < 3; ++r) lanes::store(frame[r][0] * F[0] + frame[r][1] * F[1] + frame[r][2] * F[2], Q[r][c]);
  }
  lanes::store(z0, unitNormal[0]);
  lanes::store(z1, unitNormal[1]);
  lanes::store(z2, unitNormal[2]);
  // The quaternion of Q (Shepperd's choice of the largest component, as
  // Eigen's), normalised: where the trace is positive (every lane turned by
  // less than 120° from rest) in the lanes, the other choices lane by lane.
  const Lanes trace = lanes::load(Q[0][0]) + lanes::load(Q[1][1]) + lanes::load(Q[2][2]);
  Lanes t = lanes::sqrt(trace + 1.0);
  const Lanes w = 0.5 * t;
  t = 0.5 / t;
  const Lanes x = (lanes::load(Q[2][1]) - lanes::load(Q[1][2])) * t;
  const Lanes y = (lanes::load(Q[0][2]) - lanes::load(Q[2][0])) * t;
  const Lanes z = (lanes::load(Q[1][0]) - lanes::load(Q[0][1])) * t;
  const Lanes norm = lanes::sqrt(w * w + x * x + y * y + z * z);
  lanes::store(w / norm, q.w);
  lanes::store(x / norm, q.x);
  lanes::store(y / norm, q.y);
  lanes::store(z / norm, q.z);
  double traceOf[kFitLanes], lengthOf[kFitLanes], edgeLengthOf[kFitLanes];
  lanes::store(trace, traceOf);
  lanes::store(length, lengthOf);
  lanes::store(edgeLength, edgeLengthOf);
  for (int l = 0; l < kFitLanes; ++l) {
    const bool usable = in[l].normalSquared > 0.0 && lengthOf[l] > 1e-12 * edgeLengthOf[l];
    if (!usable) {
      q.w[l] = 1.0;
      q.x[l] = q.y[l] = q.z[l] = 0.0;
      continue;
    }
    if (traceOf[l] > 0) continue;
    int i = 0;
    if (Q[1][1][l] > Q[0][0][l]) i = 1;
    if (Q[2][2][l] > Q[i][i][l]) i = 2;
    const int j = (i + 1) % 3, k = (j + 1) % 3;
    double s = std::sqrt(Q[i][i][l] - Q[j][j][l] - Q[k][k][l] + 1.0);
    double v[3];
    v[i] = 0.5 * s;
    s = 0.5 / s;
    const double wl = (Q[k][j][l] - Q[j][k][l]) * s;
    v[j] = (Q[j][i][l] + Q[i][j][l]) * s;
    v[k] = (Q[k][i][l] + Q[i][k][l]) * s;
    const double normOf = std::sqrt(wl * wl + v[0] * v[0] + v[1] * v[1] + v[2] * v[2]);
    q.w[l] = wl / normOf;
    q.x[l] = v[0] / normOf;
    q.y[l] = v[1] / normOf;
    q.z[l] = v[2] / normOf;
  }
}

void checkRows(Eigen::Index rows, Eigen::Index expected, const char* what) {
  if (rows != expected) {
    std::ostringstream s;
    s << "SurfaceGeometry: " << what << " has " << rows << " rows, expected " << expected;
    throw std::invalid_argument(s.str());
  }
}

}  // namespace

Matrix3 rotationFromCovariance(const Matrix3& covariance) {
  const Eigen::JacobiSVD<Matrix3> svd(covariance, Eigen::ComputeFullU | Eigen::ComputeFullV);
  Matrix3 U = svd.matrixU();
  const Matrix3& V = svd.matrixV();
  // Singular values are sorted decreasing: flipping the last column of U is the
  // smallest change that turns a reflection into a rotation.
  if (U.determinant() * V.determinant() < 0) U.col(2) = -U.col(2);
  return U * V.transpose();
}

Matrix3 kabschRotation(const Eigen::Ref<const Eigen::MatrixX3d>& restEdges,
                       const Eigen::Ref<const Eigen::MatrixX3d>& currentEdges) {
  if (restEdges.rows() != currentEdges.rows())
    throw std::invalid_argument("kabschRotation: rest and current edge counts differ");
  Matrix3 covariance = Matrix3::Zero();
  for (Eigen::Index k = 0; k < restEdges.rows(); ++k)
    covariance.noalias() += currentEdges.row(k).transpose() * restEdges.row(k);
  return rotationFromCovariance(covariance);
}

RotationFit fitRotation(const Matrix3& covariance, const Eigen::Quaterniond& initialGuess) {
  RotationFit fit;
  const Eigen::Quaterniond start = initialGuess.normalized();
  const Matrix3* const C[kFitLanes] = {&covariance, &covariance, &covariance, &covariance};
  LaneQuaternions q;
  for (int l = 0; l < kFitLanes; ++l) {
    q.w[l] = start.w();
    q.x[l] = start.x();
    q.y[l] = start.y();
    q.z[l] = start.z();
  }
  int iterations[kFitLanes];
  LaneStatus status[kFitLanes];
  newtonLanes(C, q, iterations, status);
  fit.iterations = iterations[0];
  if (status[0] == LaneStatus::Converged) {
    fit.rotation = Eigen::Quaterniond(q.w[0], q.x[0], q.y[0], q.z[0]);
  } else {
    fit.rotation = Eigen::Quaterniond(rotationFromCovariance(covariance));
    fit.usedSvd = true;
  }
  return fit;
}

SurfaceGeometry::SurfaceGeometry(const SurfaceTopology& topology, const RowVectors3& restPositions,
                                 const FabricField& fabric, double strainTolerance)
    : topology_(&topology), restPositions_(restPositions), fabric_(fabric),
      strainTolerance_(strainTolerance) {
  const int n = topology.vertexCount();
  const int faceCount = topology.faceCount();
  checkRows(restPositions.rows(), n, "restPositions");
  checkRows(fabric.densityTensors.rows(), faceCount, "fabric.densityTensors");
  checkRows(fabric.velocityTensors.rows(), faceCount, "fabric.velocityTensors");
  checkRows(fabric.weftDirections.rows(), faceCount, "fabric.weftDirections");
  if (!restPositions.allFinite()) throw std::invalid_argument("SurfaceGeometry: non-finite rest position");
  if (!(strainTolerance > 0) || !std::isfinite(strainTolerance))
    throw std::invalid_argument("SurfaceGeometry: strainTolerance must be finite and positive");

  ExtrinsicGeometry& ex = dynamic_.extrinsic;
  ex.previousPositions = restPositions;
  ex.positions = restPositions;
  ex.nextPositions = restPositions;
  ex.vertexNormals = vertexNormals(topology, restPositions);
  dynamic_.nextNormals = ex.vertexNormals;
  const VertexFrames restFrames = vertexTangentFrames(topology, restPositions, ex.vertexNormals);
  ex.restFrames.resize(static_cast<size_t>(n));
  for (int i = 0; i < n; ++i) ex.restFrames[static_cast<size_t>(i)] = restFrames.frame(i);
  ex.frames = ex.restFrames;
  ex.nextFrames = ex.restFrames;
  ex.kabschRotations.assign(static_cast<size_t>(n), Matrix3::Identity());
  ex.vertexAccelerations = RowVectors3::Zero(n, 3);
  ex.vertexAngularVelocities = RowVectors3::Zero(n, 3);

  const std::vector<int>& offsets = topology.ringOffsets();
  const std::vector<int>& neighbors = topology.ringNeighbors();
  restRingEdges_.resize(neighbors.size());
  for (int i = 0; i < n; ++i) {
    for (int m = offsets[static_cast<size_t>(i)]; m < offsets[static_cast<size_t>(i) + 1]; ++m) {
      const int j = neighbors[static_cast<size_t>(m)];
      restRingEdges_[static_cast<size_t>(m)] = (restPositions.row(j) - restPositions.row(i)).transpose();
    }
  }
  const int edgeCount = topology.edgeCount();
  restEdgeFrameNormals_.resize(edgeCount, 4);
  for (int e = 0; e < edgeCount; ++e) {
    const Vector3 normal = dualEdgeNormal(topology, restPositions, e);
    const Matrix3& a = ex.restFrames[static_cast<size_t>(topology.edgeVertices()(e, 0))];
    const Matrix3& b = ex.restFrames[static_cast<size_t>(topology.edgeVertices()(e, 1))];
    restEdgeFrameNormals_.row(e) << a.col(0).dot(normal), a.col(1).dot(normal), b.col(0).dot(normal),
        b.col(1).dot(normal);
  }
  dynamic_.rotations.assign(static_cast<size_t>(n), Eigen::Quaterniond::Identity());
  dynamic_.nextRotations = dynamic_.rotations;
  restNormals_ = ex.vertexNormals;
  preparedAt_.assign(static_cast<size_t>(n), refreshIndex_);
  preparedCount_ = n;

  faceWeftCoefficients_ = stain::faceWeftCoefficients(topology, restPositions, fabric.weftDirections);
  edgeMarks_.assign(static_cast<size_t>(edgeCount), 0);
  faceMarks_.assign(static_cast<size_t>(faceCount), 0);
  vertexMarks_.assign(static_cast<size_t>(n), 0);
  vertexMarks2_.assign(static_cast<size_t>(n), 0);
  for (std::vector<int>* list : {&chosenEdges_, &edges1_, &edges2_}) list->reserve(static_cast<size_t>(edgeCount));
  for (std::vector<int>* list : {&faces1_, &faces2_, &faces3_}) list->reserve(static_cast<size_t>(faceCount));
  for (std::vector<int>* list : {&vertices1_, &vertices2_, &prepareOrder_, &regionVertices_})
    list->reserve(static_cast<size_t>(n));
  refreshIntrinsic();
  kept_.valid = false;  // the first build replaced no tier: nothing to undo
}

void SurfaceGeometry::setPreviousPositions(const RowVectors3& previous) {
  checkRows(previous.rows(), topology_->vertexCount(), "previous positions");
  // The next refresh shifts `positions` into `previousPositions`.
  dynamic_.extrinsic.previousPositions = previous;
  dynamic_.extrinsic.positions = previous;
  dynamic_.extrinsic.rigid = false;
  dynamic_.unchangedRefreshes = 0;
  dynamic_.lastH = 0;
  currentEqualsPrevious_ = true;
  nextEqualsCurrent_ = previous == dynamic_.extrinsic.nextPositions;
}

void SurfaceGeometry::setVertexRefresh(VertexRefresh mode) {
  vertexRefresh_ = mode;
  if (mode == VertexRefresh::AllVertices) prepareAllVertices();
}

namespace {

// Everything of the tier that follows from in.edgeLengths before the operators.
void lengthQuantities(const SurfaceTopology& topology, IntrinsicGeometry& in) {
  // Into the tier's arrays: no allocation once they have the mesh's sizes.
  faceAnglesAreasAndCotanWeights(topology, in.edgeLengths, in.faceCornerAngles, in.faceAreas, in.edgeCotanWeights);
  vertexDualAreas(topology, in.faceAreas, in.vertexDualAreas);
  geodesicPolarMap(topology, in.faceCornerAngles, in.polarMap);
  edgeTransportAngles(topology, in.polarMap, in.edgeTransportAngles);
  faceTransportAngles(topology, in.faceCornerAngles, in.polarMap, in.faceTransportAngles);
}

}  // namespace

void intrinsicGeometryFromLengths(const SurfaceTopology& topology, const Vector& lengths,
                                  const Eigen::MatrixX3d& densityTensors, const Eigen::MatrixX3d& velocityTensors,
                                  const Eigen::MatrixX2d& faceWeftCoefficients, IntrinsicGeometry& in) {
  in.edgeLengths = lengths;
  lengthQuantities(topology, in);
  in.densityStiffness = anisotropicStiffnessFromLengths(topology, in.edgeLengths, densityTensors, faceWeftCoefficients);
  in.velocityStiffness = connectionLaplacianFromLengths(topology, in.edgeLengths, in.faceTransportAngles,
                                                        velocityTensors, faceWeftCoefficients);
}

void SurfaceGeometry::setIntrinsicRefresh(IntrinsicRefresh mode) {
  if (mode != IntrinsicRefresh::Full && intrinsicRefresh_ == IntrinsicRefresh::Full && dynamic_.intrinsic.rebuildCount > 0) {
    IntrinsicGeometry& in = dynamic_.intrinsic;
    const Vector built = in.edgeLengths;
    intrinsicGeometryFromLengths(*topology_, built, fabric_.densityTensors, fabric_.velocityTensors,
                                 faceWeftCoefficients_, in);
    kept_.valid = false;
  }
  intrinsicRefresh_ = mode;
  if (mode != IntrinsicRefresh::Full) {
    // The table of the partial re-assemblies' entry positions.
    if (faceEntries_.index.empty()) faceEntries_ = oneRingFaceEntries(*topology_);
    // The most a partial refresh can journal: every value forEachRefreshedValue reaches.
    const IntrinsicGeometry& in = dynamic_.intrinsic;
    const size_t edges = static_cast<size_t>(topology_->edgeCount());
    const size_t faces = static_cast<size_t>(topology_->faceCount());
    const size_t vertices = static_cast<size_t>(topology_->vertexCount());
    kept_.journal.reserve(5 * edges + 7 * faces + 2 * vertices + topology_->ringNeighbors().size() +
                          static_cast<size_t>(in.densityStiffness.nonZeros()) +
                          2 * static_cast<size_t>(in.velocityStiffness.nonZeros()));
  }
}

void SurfaceGeometry::setRefreshRegion(const int* vertices, int count) {
  if (count < 0 || count > topology_->vertexCount())
    throw std::invalid_argument("SurfaceGeometry::setRefreshRegion: " + std::to_string(count) +
                                " vertices, expected at most " + std::to_string(topology_->vertexCount()));
  for (int k = 0; k < count; ++k)
    if (vertices[k] < 0 || vertices[k] >= topology_->vertexCount())
      throw std::invalid_argument("SurfaceGeometry::setRefreshRegion: vertex " + std::to_string(vertices[k]) +
                                  " out of range");
  regionVertices_.assign(vertices, vertices + count);
}

void SurfaceGeometry::refreshIntrinsic() {
  const RowVectors3& positions = dynamic_.extrinsic.nextPositions;
  IntrinsicGeometry& in = dynamic_.intrinsic;
  kept_.maxEdgeStrain = dynamic_.maxEdgeStrain;
  kept_.strainMeasured = strainMeasured_;
  // Partial and Region choose their edges first (reading the tier, writing
  // none of it): a refresh that stays partial journals the values it is
  // about to write (refreshChosenEdges) and updates the tier in place. Full,
  // and a choice past kPartialRefreshMaxShare,
  // rebuild the whole tier from the current lengths into the kept tier's
  // arrays (swapped in, the old tier kept by the swap: no copy, no
  // allocation), the same bits as intrinsicGeometryFromLengths.
  const bool partial = intrinsicRefresh_ != IntrinsicRefresh::Full && in.rebuildCount > 0 &&
                       chooseRefreshedEdges(positions);
  const bool whole = !partial && (intrinsicRefresh_ == IntrinsicRefresh::Full || in.rebuildCount > 0);
  kept_.journaled = partial;
  kept_.rebuildCount = in.rebuildCount;
  lastRefreshPartial_ = false;  // until the partial refresh below completes
  if (whole) {
    swap(kept_.intrinsic, in);
    kept_.inverseBuiltSquaredLengths.swap(dynamic_.inverseBuiltSquaredLengths);
    in.rebuildCount = kept_.intrinsic.rebuildCount;
  } else if (!partial) {
    kept_.intrinsic = in;
    kept_.inverseBuiltSquaredLengths = dynamic_.inverseBuiltSquaredLengths;
  }
  // The undo point is set before anything below can throw (a face that
  // cannot be laid out): the caller gives the old tier back with it.
  kept_.valid = true;
  if (partial) {
    refreshChosenEdges(positions);
    lastRefreshPartial_ = true;
  } else if (whole) {
    refreshIntrinsicFromPositions(positions);
  } else {
    // The first build of a Partial geometry: every edge measured, the tier from the lengths.
    intrinsicGeometryFromLengths(*topology_, edgeLengths(*topology_, positions), fabric_.densityTensors,
                                 fabric_.velocityTensors, faceWeftCoefficients_, in);
    dynamic_.inverseBuiltSquaredLengths = in.edgeLengths.array().square().inverse().matrix();
    dynamic_.maxEdgeStrain = 0;
    strainMeasured_ = true;
    refreshedEdges_ = topology_->edgeCount();
    refreshedFaces_ = topology_->faceCount();
  }
  ++in.rebuildCount;
}

void SurfaceGeometry::prepareWholeRebuilds() {
  const SurfaceTopology& topology = *topology_;
  if (faceEntries_.index.empty()) faceEntries_ = oneRingFaceEntries(topology);
  if (!kept_.valid && (!faceEntries_.fits(topology, kept_.intrinsic.densityStiffness) ||
                       !faceEntries_.fits(topology, kept_.intrinsic.velocityStiffness))) {
    // Every array of the tier at its size, and operators of the one-ring
    // pattern the refill writes into (the first build's own).
    kept_.intrinsic = dynamic_.intrinsic;
    kept_.inverseBuiltSquaredLengths = dynamic_.inverseBuiltSquaredLengths;
  }
}

void SurfaceGeometry::undoIntrinsicRefresh() {
  if (!kept_.valid) throw std::logic_error("SurfaceGeometry::undoIntrinsicRefresh: no refresh to undo");
  if (kept_.journaled) {
    // The journal holds every value the refresh wrote (all of them saved
    // before the first write, so also after a refresh that threw).
    size_t k = 0;
    const auto restore = [&](double& value) { value = kept_.journal[k++]; };
    forEachRefreshedValue(0, restore);
    forEachRefreshedValue(1, restore);
    dynamic_.intrinsic.rebuildCount = kept_.rebuildCount;
    kept_.journaled = false;
  } else {
    swap(kept_.intrinsic, dynamic_.intrinsic);
    kept_.inverseBuiltSquaredLengths.swap(dynamic_.inverseBuiltSquaredLengths);
  }
  dynamic_.maxEdgeStrain = kept_.maxEdgeStrain;
  strainMeasured_ = kept_.strainMeasured;
  kept_.valid = false;
  lastRefreshPartial_ = false;  // the lists describe a refresh that no longer is
}

void SurfaceGeometry::refreshIntrinsicFromPositions(const RowVectors3& positions) {
  const SurfaceTopology& topology = *topology_;
  IntrinsicGeometry& in = dynamic_.intrinsic;
  edgeLengths(topology, positions, in.edgeLengths);
  lengthQuantities(topology, in);
  if (in.rebuildCount == 0) {
    // The first build is on the rest shape, where the given wefts apply as they are.
    in.densityStiffness = anisotropicStiffness(topology, positions, fabric_.densityTensors, fabric_.weftDirections);
    in.velocityStiffness = connectionLaplacian(topology, positions, in.faceTransportAngles, fabric_.velocityTensors,
                                               fabric_.weftDirections);
  } else {
    // A rebuild lays each face out from the lengths it has just measured,
    // as every other tier path does (design note): no frames from positions.
    if (faceEntries_.index.empty()) faceEntries_ = oneRingFaceEntries(topology);
    if (!faceEntries_.fits(topology, in.densityStiffness) || !faceEntries_.fits(topology, in.velocityStiffness)) {
      in.densityStiffness =
          anisotropicStiffnessFromLengths(topology, in.edgeLengths, fabric_.densityTensors, faceWeftCoefficients_);
      in.velocityStiffness = connectionLaplacianFromLengths(topology, in.edgeLengths, in.faceTransportAngles,
                                                            fabric_.velocityTensors, faceWeftCoefficients_);
    } else {
      // The same values, into the existing patterns: no pattern build, no
      // search for each entry, no new matrices, each face laid out once.
      refillStiffnessAndConnectionFromLengths(topology, in.edgeLengths, in.faceAreas, fabric_.densityTensors,
                                              in.faceTransportAngles, fabric_.velocityTensors,
                                              faceWeftCoefficients_, faceEntries_, in.densityStiffness,
                                              in.velocityStiffness);
    }
  }
  dynamic_.inverseBuiltSquaredLengths = in.edgeLengths.array().square().inverse().matrix();
  dynamic_.maxEdgeStrain = 0;
  strainMeasured_ = true;
  refreshedEdges_ = topology.edgeCount();
  refreshedFaces_ = topology.faceCount();
}

void SurfaceGeometry::markRegionEdges() {
  const SurfaceTopology& topology = *topology_;
  const std::vector<int>& offsets = topology.ringOffsets();
  const std::vector<int>& neighbors = topology.ringNeighbors();
  const std::vector<int>& ringFaces = topology.ringFaces();
  const Eigen::MatrixX3i& faceEdges = topology.faceEdges();
  // The region's vertices, then kRegionRefreshRings rings around them, ring
  // by ring (vertices1_ as the list, vertexMarks_ as its marks).
  vertices1_.clear();
  const auto add = [&](int v) {
    if (vertexMarks_[static_cast<size_t>(v)]) return;
    vertexMarks_[static_cast<size_t>(v)] = 1;
    vertices1_.push_back(v);
  };
  for (const int v : regionVertices_) add(v);
  size_t ringBegin = 0;
  for (int ring = 0; ring < kRegionRefreshRings; ++ring) {
    const size_t ringEnd = vertices1_.size();
    for (size_t k = ringBegin; k < ringEnd; ++k) {
      const size_t v = static_cast<size_t>(vertices1_[k]);
      for (int m = offsets[v]; m < offsets[v + 1]; ++m) add(neighbors[static_cast<size_t>(m)]);
    }
    ringBegin = ringEnd;
  }
  // Their faces' edges; the vertex marks cleared.
  for (const int v : vertices1_) {
    vertexMarks_[static_cast<size_t>(v)] = 0;
    for (int m = offsets[static_cast<size_t>(v)]; m < offsets[static_cast<size_t>(v) + 1]; ++m) {
      const int f = ringFaces[static_cast<size_t>(m)];
      if (f < 0) continue;
      for (int c = 0; c < 3; ++c) edgeMarks_[static_cast<size_t>(faceEdges(f, c))] = 1;
    }
  }
}

bool SurfaceGeometry::chooseRefreshedEdges(const RowVectors3& positions) {
  const SurfaceTopology& topology = *topology_;
  const int edgeCount = topology.edgeCount();
  const Eigen::MatrixX2i& edges = topology.edgeVertices();
  const double* inverseBuilt = dynamic_.inverseBuiltSquaredLengths.data();

  // Chosen edges: r_e = ℓ_e² / ℓ̂_e² outside [(1 − t)², (1 + t)²], t the
  // fraction of the tolerance (the strain test's ratio, so no root per edge).
  const double t = kPartialRefreshFraction * strainTolerance_;
  const double high = (1 + t) * (1 + t), low = t < 1 ? (1 - t) * (1 - t) : 0.0;
  chosenEdges_.clear();
  const bool region = intrinsicRefresh_ == IntrinsicRefresh::Region;
  if (region) markRegionEdges();
  double maxRatio = 1.0, minRatio = 1.0;
  for (int e = 0; e < edgeCount; ++e) {
    const Vector3 d = (positions.row(edges(e, 1)) - positions.row(edges(e, 0))).transpose();
    const double ratio = d.squaredNorm() * inverseBuilt[e];
    if (region ? edgeMarks_[static_cast<size_t>(e)] != 0 : (ratio > high || ratio < low)) {
      chosenEdges_.push_back(e);
    } else {
      maxRatio = std::max(maxRatio, ratio);
      minRatio = std::min(minRatio, ratio);
    }
  }
  if (static_cast<double>(chosenEdges_.size()) > kPartialRefreshMaxShare * edgeCount) {
    for (const int e : chosenEdges_) edgeMarks_[static_cast<size_t>(e)] = 0;
    return false;
  }
  unchosenStrain_ = strainFromSquaredRatios(maxRatio, minRatio);
  return true;
}

template <class At>
void SurfaceGeometry::forEachRefreshedValue(int part, const At& at) {
  IntrinsicGeometry& in = dynamic_.intrinsic;
  if (part == 0) {
    for (const int e : chosenEdges_) {
      at(in.edgeLengths(e));
      at(dynamic_.inverseBuiltSquaredLengths(e));
    }
    return;
  }
  const std::vector<int>& offsets = topology_->ringOffsets();
  for (const int f : faces1_) {
    for (int k = 0; k < 3; ++k) at(in.faceCornerAngles(f, k));
    at(in.faceAreas(f));
  }
  for (const int e : edges1_) at(in.edgeCotanWeights(e));
  for (const int v : vertices1_) {
    at(in.vertexDualAreas(v));
    at(in.polarMap.vertexAngleScales(v));
    for (int m = offsets[static_cast<size_t>(v)]; m < offsets[static_cast<size_t>(v) + 1]; ++m)
      at(in.polarMap.ringAngles(m));
  }
  for (const int e : edges2_) at(in.edgeTransportAngles(e));
  for (const int f : faces2_)  // every face updateFaceTransportAngles writes a corner of
    for (int k = 0; k < 3; ++k) at(in.faceTransportAngles(f, k));
  // The re-assemblies write entries in the columns of V1 (L_S) and V2 (connection) only.
  const int* outer = in.densityStiffness.outerIndexPtr();
  double* density = in.densityStiffness.valuePtr();
  for (const int v : vertices1_)
    for (int q = outer[v]; q < outer[v + 1]; ++q) at(density[q]);
  const int* connectionOuter = in.velocityStiffness.outerIndexPtr();
  // std::complex<double> is two doubles (re, im) by the standard's array rule.
  double* connection = reinterpret_cast<double*>(in.velocityStiffness.valuePtr());
  for (const int v : vertices2_)
    for (int q = connectionOuter[v]; q < connectionOuter[v + 1]; ++q) {
      at(connection[2 * q]);
      at(connection[2 * q + 1]);
    }
}

void SurfaceGeometry::refreshChosenEdges(const RowVectors3& positions) {
  const SurfaceTopology& topology = *topology_;
  const int n = topology.vertexCount(), edgeCount = topology.edgeCount(), faceCount = topology.faceCount();
  const Triangles& faces = topology.faces();
  const Eigen::MatrixX3i& faceEdges = topology.faceEdges();
  const Eigen::MatrixX2i& edges = topology.edgeVertices();
  const std::vector<int>& offsets = topology.ringOffsets();
  const std::vector<int>& ringFaces = topology.ringFaces();
  const std::vector<int>& ringEdges = topology.ringEdges();
  IntrinsicGeometry& in = dynamic_.intrinsic;
  double* inverseBuilt = dynamic_.inverseBuiltSquaredLengths.data();
  kept_.journal.clear();
  const auto save = [&](double& value) { kept_.journal.push_back(value); };
  forEachRefreshedValue(0, save);
  for (const int e : chosenEdges_) {
    // What edgeLengths() computes for this edge, and 1 / ℓ̂² as the whole path does.
    in.edgeLengths(e) = (positions.row(edges(e, 1)) - positions.row(edges(e, 0))).norm();
    inverseBuilt[e] = 1.0 / (in.edgeLengths(e) * in.edgeLengths(e));
    edgeMarks_[static_cast<size_t>(e)] = 1;
  }
  // F1: faces with a chosen edge; V1 their vertices; their edges (cotan weights).
  faces1_.clear();
  for (int f = 0; f < faceCount; ++f) {
    if (!(edgeMarks_[static_cast<size_t>(faceEdges(f, 0))] | edgeMarks_[static_cast<size_t>(faceEdges(f, 1))] |
          edgeMarks_[static_cast<size_t>(faceEdges(f, 2))]))
      continue;
    faces1_.push_back(f);
    for (int k = 0; k < 3; ++k) vertexMarks_[static_cast<size_t>(faces(f, k))] = 1;
  }
  for (const int e : chosenEdges_) edgeMarks_[static_cast<size_t>(e)] = 0;
  for (const int f : faces1_)
    for (int k = 0; k < 3; ++k) edgeMarks_[static_cast<size_t>(faceEdges(f, k))] = 1;
  // The marked ids of `marks` (size `count`), ascending, into `list`; the
  // marks are cleared unless `keep`.
  const auto collect = [](std::vector<char>& marks, int count, std::vector<int>& list, bool keep) {
    list.clear();
    for (int i = 0; i < count; ++i) {
      if (!marks[static_cast<size_t>(i)]) continue;
      list.push_back(i);
      if (!keep) marks[static_cast<size_t>(i)] = 0;
    }
  };
  collect(edgeMarks_, edgeCount, edges1_, false);
  collect(vertexMarks_, n, vertices1_, true);  // kept: the L_S re-assembly reads them
  // F2: ring faces of V1; edges at V1 (transport angles).
  for (const int v : vertices1_) {
    for (int m = offsets[static_cast<size_t>(v)]; m < offsets[static_cast<size_t>(v) + 1]; ++m) {
      const int f = ringFaces[static_cast<size_t>(m)];
      if (f >= 0) faceMarks_[static_cast<size_t>(f)] = 1;
      edgeMarks_[static_cast<size_t>(ringEdges[static_cast<size_t>(m)])] = 1;
    }
  }
  collect(faceMarks_, faceCount, faces2_, false);
  collect(edgeMarks_, edgeCount, edges2_, false);
  // V2: vertices of F2 (kept for the connection re-assembly); F3: their ring faces.
  for (const int f : faces2_)
    for (int k = 0; k < 3; ++k) vertexMarks2_[static_cast<size_t>(faces(f, k))] = 1;
  collect(vertexMarks2_, n, vertices2_, true);
  for (const int v : vertices2_)
    for (int m = offsets[static_cast<size_t>(v)]; m < offsets[static_cast<size_t>(v) + 1]; ++m) {
      const int f = ringFaces[static_cast<size_t>(m)];
      if (f >= 0) faceMarks_[static_cast<size_t>(f)] = 1;
    }
  collect(faceMarks_, faceCount, faces3_, false);
  forEachRefreshedValue(1, save);

  // The values, in dependency order (each update writes what the whole
  // function writes for those elements).
  const auto size = [](const std::vector<int>& list) { return static_cast<int>(list.size()); };
  updateFaceAnglesAndAreas(topology, in.edgeLengths, faces1_.data(), size(faces1_), in.faceCornerAngles, in.faceAreas);
  updateEdgeCotanWeights(topology, in.edgeLengths, in.faceAreas, edges1_.data(), size(edges1_), in.edgeCotanWeights);
  updateVertexDualAreas(topology, in.faceAreas, vertices1_.data(), size(vertices1_), in.vertexDualAreas);
  updateGeodesicPolarMap(topology, in.faceCornerAngles, vertices1_.data(), size(vertices1_), in.polarMap);
  updateEdgeTransportAngles(topology, in.polarMap, edges2_.data(), size(edges2_), in.edgeTransportAngles);
  updateFaceTransportAngles(topology, in.faceCornerAngles, in.polarMap, vertices1_.data(), size(vertices1_),
                            in.faceTransportAngles);
  const auto clearVertexMarks = [&] {
    for (const int v : vertices1_) vertexMarks_[static_cast<size_t>(v)] = 0;
    for (const int v : vertices2_) vertexMarks2_[static_cast<size_t>(v)] = 0;
  };
  try {
    // L_S: blocks of F1 changed; entries among V1, re-summed over F2 (every face at V1).
    reassembleStiffnessFromLengths(topology, in.edgeLengths, fabric_.densityTensors, faceWeftCoefficients_,
                                   vertexMarks_.data(), vertices1_.data(), size(vertices1_), faces2_.data(),
                                   size(faces2_), in.densityStiffness, &faceEntries_);
    // Connection: blocks of F2 changed (transport angles); entries among V2, over F3.
    reassembleConnectionFromLengths(topology, in.edgeLengths, in.faceTransportAngles, fabric_.velocityTensors,
                                    faceWeftCoefficients_, vertexMarks2_.data(), vertices2_.data(),
                                    size(vertices2_), faces3_.data(), size(faces3_), in.velocityStiffness,
                                    &faceEntries_);
  } catch (...) {
    // A face whose weft cannot be laid out (a collapsed anisotropic face):
    // the caller undoes the tier; the marks must not outlive this refresh,
    // or the next one would re-assemble around these vertices too.
    clearVertexMarks();
    throw;
  }
  clearVertexMarks();
  dynamic_.maxEdgeStrain = unchosenStrain_;
  strainMeasured_ = true;
  refreshedEdges_ = size(chosenEdges_);
  refreshedFaces_ = size(faces3_);
}

bool SurfaceGeometry::refreshExtrinsic(const RowVectors3& nextPositions, double h, bool strainTest) {
  return refreshExtrinsicWith(nextPositions, h, nullptr, strainTest);
}

bool SurfaceGeometry::refreshExtrinsicRigid(const RowVectors3& nextPositions, const Matrix3& rotation,
                                            double h) {
  if (!rotation.allFinite() || (rotation.transpose() * rotation - Matrix3::Identity()).cwiseAbs().maxCoeff() > 1e-9 ||
      !(rotation.determinant() > 0))
    throw std::invalid_argument("SurfaceGeometry::refreshExtrinsicRigid: not a rotation matrix");
#ifdef BLOT_VALIDATE
  // The caller promises p = R x̄ + c: check it against vertex 0.
  checkRows(nextPositions.rows(), topology_->vertexCount(), "nextPositions");
  const Vector3 offset = (nextPositions.row(0) - restPositions_.row(0) * rotation.transpose()).transpose();
  const double scale = 1.0 + restPositions_.cwiseAbs().maxCoeff() + offset.norm();
  for (Eigen::Index i = 0; i < nextPositions.rows(); ++i) {
    const Vector3 expected = rotation * restPositions_.row(i).transpose() + offset;
    if ((nextPositions.row(i).transpose() - expected).norm() > 1e-9 * scale)
      throw std::logic_error("SurfaceGeometry::refreshExtrinsicRigid: vertex " + std::to_string(i) +
                             " does not follow the rigid motion");
  }
#endif
  return refreshExtrinsicWith(nextPositions, h, &rotation, true);
}

bool SurfaceGeometry::refreshExtrinsicWith(const RowVectors3& nextPositions, double h,
                                           const Matrix3* rigidRotation, bool strainTest) {
  const SurfaceTopology& topology = *topology_;
  const int n = topology.vertexCount();
  checkRows(nextPositions.rows(), n, "nextPositions");
  if (!(h > 0) || !std::isfinite(h)) throw std::invalid_argument("SurfaceGeometry: h must be finite and positive");
  ExtrinsicGeometry& ex = dynamic_.extrinsic;
  rotationFitStats_ = RotationFitStats();

  const bool unchanged = nextPositions == ex.nextPositions;
  // A still surface whose slots are rigid never measures strain (below), so
  // the shortcut does not wait for a measurement there: after a restore,
  // which clears strainMeasured_, a static surface re-shifted every step.
  if (unchanged && dynamic_.unchangedRefreshes >= 2 && (strainMeasured_ || !strainTest || ex.nextRigid)) {
    // t − h, t and t + h all hold these positions already; ω = p̈ = 0, and
    // every vertex prepared since the last shift keeps its values.
    dynamic_.lastH = h;
    return dynamic_.maxEdgeStrain > strainTolerance_;
  }
  const double previousH = dynamic_.lastH > 0 ? dynamic_.lastH : h;
  dynamic_.lastH = h;

  // Shift t + h -> t -> t − h by swapping buffers (no allocation, no copy).
  ex.previousPositions.swap(ex.positions);
  ex.positions.swap(ex.nextPositions);
  ex.nextPositions = nextPositions;  // same size: copies into the existing buffer
  ex.frames.swap(ex.nextFrames);
  ex.rigid = ex.nextRigid;
  ex.vertexNormals.swap(dynamic_.nextNormals);
  dynamic_.rotations.swap(dynamic_.nextRotations);
  currentRule_ = nextRule_;
  currentEqualsPrevious_ = nextEqualsCurrent_;
  nextEqualsCurrent_ = unchanged;
  ++refreshIndex_;
  preparedCount_ = 0;
  rates_ = RateRule();
  rates_.h = h;
  rates_.previousH = previousH;
  rates_.still = unchanged;

  if (unchanged) {
    // The surface did not move over [t, t + h]: U, frames and normals at t + h
    // are those at t (same rule, same positions); only p̈ may still be
    // non-zero (the surface just stopped).
    ex.nextRigid = ex.rigid;
    ++dynamic_.unchangedRefreshes;
    if (strainTest && !strainMeasured_ && !ex.nextRigid) measureStrain();
  } else {
    dynamic_.unchangedRefreshes = 0;
    if (rigidRotation != nullptr) {
      // Known rigid motion: U_i = R for every vertex (the Kabsch fit of a rigid
      // motion), normals R n̄ (n̄ = F̄ z), no fits, and no strain to measure.
      // When U^t was one rotation for every vertex too, the rotation vector of
      // U^tᵀ U^{t+h} is one vector: computed once.
      ex.nextRigid = true;
      nextRule_.kind = SlotKind::Rigid;
      nextRule_.matrix = *rigidRotation;
      nextRule_.rotation = Eigen::Quaterniond(*rigidRotation);
      if (currentRule_.kind != SlotKind::Fitted) {
        rates_.shared = true;
        rates_.sharedAxis = rotationVector(currentRule_.rotation.conjugate() * nextRule_.rotation);
      }
    } else {
      ex.nextRigid = false;
      nextRule_ = SlotRule();
      nextRule_.kind = SlotKind::Fitted;
      // The strain test, per edge (the fits are per vertex and may not run).
      if (strainTest) {
        measureStrain();
      } else {
        dynamic_.maxEdgeStrain = 0.0;
        strainMeasured_ = false;
      }
    }
  }
  dynamic_.nextSlotKind = static_cast<int>(nextRule_.kind);
  if (vertexRefresh_ == VertexRefresh::AllVertices) prepareAllVertices();
  return dynamic_.maxEdgeStrain > strainTolerance_;
}

bool SurfaceGeometry::strainExceededAround(const int* vertices, int count) {
  const SurfaceTopology& topology = *topology_;
  const int n = topology.vertexCount();
  const std::vector<int>& offsets = topology.ringOffsets();
  const std::vector<int>& ringFaces = topology.ringFaces();
  const Eigen::MatrixX3i& faceEdges = topology.faceEdges();
  // Each edge once: marked, listed, then measured and unmarked (the list
  // holds at most #E ids, its reserved capacity).
  chosenEdges_.clear();
  for (int k = 0; k < count; ++k) {
    const int v = vertices[k];
    for (int m = offsets[static_cast<size_t>(v)]; m < offsets[static_cast<size_t>(v) + 1]; ++m) {
      const int f = ringFaces[static_cast<size_t>(m)];
      if (f < 0) continue;
      for (int c = 0; c < 3; ++c) {
        const int e = faceEdges(f, c);
        if (edgeMarks_[static_cast<size_t>(e)]) continue;
        edgeMarks_[static_cast<size_t>(e)] = 1;
        chosenEdges_.push_back(e);
      }
    }
  }
  const Eigen::Matrix<int, Eigen::Dynamic, 2>& edges = topology.edgeVertices();
  const double* x = dynamic_.extrinsic.nextPositions.data();
  const double* y = x + n;
  const double* z = y + n;
  const double* inverseBuilt = dynamic_.inverseBuiltSquaredLengths.data();
  double maxRatio = 1.0, minRatio = 1.0;
  for (const int e : chosenEdges_) {
    edgeMarks_[static_cast<size_t>(e)] = 0;
    const int a = edges(e, 0), b = edges(e, 1);
    const double dx = x[b] - x[a], dy = y[b] - y[a], dz = z[b] - z[a];
    const double ratio = (dx * dx + dy * dy + dz * dz) * inverseBuilt[e];
    maxRatio = std::max(maxRatio, ratio);
    minRatio = std::min(minRatio, ratio);
  }
  dynamic_.maxEdgeStrain = strainFromSquaredRatios(maxRatio, minRatio);
  strainMeasured_ = false;  // not the whole surface's
  return dynamic_.maxEdgeStrain > strainTolerance_;
}

void SurfaceGeometry::measureStrain() {
  const SurfaceTopology& topology = *topology_;
  const int n = topology.vertexCount();
  const Eigen::Matrix<int, Eigen::Dynamic, 2>& edges = topology.edgeVertices();
  const int edgeCount = topology.edgeCount();
  const double* x = dynamic_.extrinsic.nextPositions.data();
  const double* y = x + n;
  const double* z = y + n;
  const double* inverseBuilt = dynamic_.inverseBuiltSquaredLengths.data();
  double maxRatio = 1.0, minRatio = 1.0;
  threads::runLoop(edgeCount >= 4 * kMinParallelVertices, [&] {
    decltype(maxRatio) maxRatioHere = threads::lowest<decltype(maxRatio)>();
    decltype(minRatio) minRatioHere = threads::highest<decltype(minRatio)>();
#pragma omp for schedule(static) nowait
    for (int e = 0; e < edgeCount; ++e) {
      const int a = edges(e, 0), b = edges(e, 1);
      const double dx = x[b] - x[a], dy = y[b] - y[a], dz = z[b] - z[a];
      const double ratio = (dx * dx + dy * dy + dz * dz) * inverseBuilt[e];
      maxRatioHere = std::max(maxRatioHere, ratio);
      minRatioHere = std::min(minRatioHere, ratio);
    }
#pragma omp critical(blot_threads_combine)
    {
      maxRatio = std::max(maxRatio, maxRatioHere);
      minRatio = std::min(minRatio, minRatioHere);
    }
  });
  dynamic_.maxEdgeStrain = strainFromSquaredRatios(maxRatio, minRatio);
  strainMeasured_ = true;
}

void SurfaceGeometry::evaluateSlot(const SlotRule& rule, int i, Eigen::Quaterniond& rotation, Matrix3& frame,
                                   RowVectors3& normals, Matrix3& fit) const {
  const Matrix3& restFrame = dynamic_.extrinsic.restFrames[static_cast<size_t>(i)];
  if (rule.kind == SlotKind::Rest) {
    rotation = Eigen::Quaterniond::Identity();
    frame = restFrame;
    normals.row(i) = restNormals_.row(i);
    fit = Matrix3::Identity();
    return;
  }
  rotation = rule.rotation;
  fit = rule.matrix;
  frame.noalias() = rule.matrix * restFrame;
  normals.row(i) = frame.col(2).transpose();
}

void SurfaceGeometry::sampleSlot(const RowVectors3& positions, int i, SlotFit& job) const {
  const SurfaceTopology& topology = *topology_;
  const std::vector<int>& offsets = topology.ringOffsets();
  const std::vector<int>& neighbors = topology.ringNeighbors();
  const int n = topology.vertexCount();
  const size_t k = static_cast<size_t>(i);
  const double* x = positions.data();
  const double* y = x + n;
  const double* z = y + n;
  // The fit reads the rest frame after every slot of its group is sampled:
  // asked for now, its two lines (cold after a cloth step) arrive meanwhile.
  const char* restFrame = reinterpret_cast<const char*>(&dynamic_.extrinsic.restFrames[k]);
  __builtin_prefetch(restFrame);
  __builtin_prefetch(restFrame + sizeof(Matrix3) - 1);
  const int begin = offsets[k], end = offsets[k + 1];
  const double xi = x[i], yi = y[i], zi = z[i];
  Matrix3 covariance = Matrix3::Zero();
  Vector3 normalSum = Vector3::Zero();
  Vector3 first = Vector3::Zero(), previous = Vector3::Zero();
  for (int m = begin; m < end; ++m) {
    const size_t mk = static_cast<size_t>(m);
    const int j = neighbors[mk];
    const Vector3 e(x[j] - xi, y[j] - yi, z[j] - zi);
    covariance.noalias() += e * restRingEdges_[mk].transpose();
    if (m == begin) {
      first = e;
    } else {
      normalSum += previous.cross(e);
    }
    previous = e;
  }
  if (!topology.vertexIsBoundary()[k]) normalSum += previous.cross(first);  // the ring's closing face
  job.vertex = i;
  job.covariance = covariance;
  job.normal = normalSum;
  job.normalSquared = normalSum.squaredNorm();
  job.edge = first;
}

void SurfaceGeometry::fitSlots(SlotFit* jobs, int count, FitCounts& counts) const {
  const std::vector<Matrix3>& restFrames = dynamic_.extrinsic.restFrames;
  // The slot's normal once its frame is written: n / |n| (unit), or, where a
  // fully folded fan has none, the fitted frame's.
  const auto setNormal = [](SlotFit& job, const double (&unit)[3]) {
    for (int c = 0; c < 3; ++c)
      (*job.normals)(job.vertex, c) = job.normalSquared > 0.0 ? unit[c] : (*job.frame)(c, 2);
  };
  const auto finish = [&](SlotFit& job, const Eigen::Quaterniond& q, const Matrix3& U) {
    *job.rotation = q;
    *job.fit = U;
    job.frame->noalias() = U * restFrames[static_cast<size_t>(job.vertex)];
    double unit[3] = {0.0, 0.0, 0.0};
    if (job.normalSquared > 0.0) {
      const double inverse = 1.0 / std::sqrt(job.normalSquared);
      for (int c = 0; c < 3; ++c) unit[c] = job.normal(c) * inverse;
    }
    setNormal(job, unit);
    ++counts.fitted;
  };
  if (rotationFitMethod_ == RotationFitMethod::Svd) {
    for (int k = 0; k < count; ++k) {
      const Matrix3 U = rotationFromCovariance(jobs[k].covariance);
      finish(jobs[k], Eigen::Quaterniond(U), U);
    }
    return;
  }
  for (int start = 0; start < count; start += kFitLanes) {
    const int used = std::min(kFitLanes, count - start);
    FitInputs in[kFitLanes];
    const Matrix3* C[kFitLanes];
    for (int l = 0; l < kFitLanes; ++l) {
      const SlotFit& job = jobs[start + std::min(l, used - 1)];
      in[l] = {&job.normal, job.normalSquared, &job.edge, &restFrames[static_cast<size_t>(job.vertex)]};
      C[l] = &job.covariance;
    }
    LaneQuaternions q;
    double unitNormal[3][kFitLanes];
    lanes::Lanes restFrame[9];
    frameGuessLanes(in, q, unitNormal, restFrame);
    int iterations[kFitLanes];
    LaneStatus status[kFitLanes];
    newtonLanes(C, q, iterations, status);
    // U and the frame U F̄ of every lane (lanes::product3: Eigen's bits).
    lanes::Lanes U[9], frame[9];
    laneRotationMatrices(lanes::load(q.w), lanes::load(q.x), lanes::load(q.y), lanes::load(q.z), U);
    lanes::product3(U, restFrame, frame);
    double UOf[9][kFitLanes], frameOf[9][kFitLanes];
    for (int e = 0; e < 9; ++e) {
      lanes::store(U[e], UOf[e]);
      lanes::store(frame[e], frameOf[e]);
    }
    for (int l = 0; l < used; ++l) {
      SlotFit& job = jobs[start + l];
      counts.iterations += iterations[l];
      if (status[l] != LaneStatus::Converged) {
        ++counts.fallbacks;
        const Matrix3 fitted = rotationFromCovariance(job.covariance);
        finish(job, Eigen::Quaterniond(fitted), fitted);
        continue;
      }
      // What finish writes, from the lanes.
      *job.rotation = Eigen::Quaterniond(q.w[l], q.x[l], q.y[l], q.z[l]);
      for (int r = 0; r < 3; ++r)
        for (int c = 0; c < 3; ++c) {
          (*job.fit)(r, c) = UOf[3 * r + c][l];
          (*job.frame)(r, c) = frameOf[3 * r + c][l];
        }
      setNormal(job, {unitNormal[0][l], unitNormal[1][l], unitNormal[2][l]});
      ++counts.fitted;
    }
  }
}

void SurfaceGeometry::prepareGroup(DynamicState& d, const int* vertices, const bool* currentValid, int count,
                                   FitCounts& counts) const {
  ExtrinsicGeometry& ex = d.extrinsic;
  SlotFit jobs[2 * kPrepareGroup];
  Matrix3 unused[kPrepareGroup];
  int jobCount = 0;
  // A slot's values: fitted in the lanes below, or from its rule.
  const auto slot = [&](const SlotRule& rule, const RowVectors3& positions, int i, Eigen::Quaterniond& rotation,
                        Matrix3& frame, RowVectors3& normals, Matrix3& fit) {
    if (rule.kind != SlotKind::Fitted) {
      evaluateSlot(rule, i, rotation, frame, normals, fit);
      return;
    }
    SlotFit& job = jobs[jobCount++];
    sampleSlot(positions, i, job);
    job.rotation = &rotation;
    job.frame = &frame;
    job.normals = &normals;
    job.fit = &fit;
  };
  for (int g = 0; g < count; ++g) {
    const int i = vertices[g];
    const size_t k = static_cast<size_t>(i);
    __builtin_prefetch(&d.rotations[k]);  // read by finishVertex (ω), cold since the last step
    if (!currentValid[g])
      slot(currentRule_, ex.positions, i, d.rotations[k], ex.frames[k], ex.vertexNormals,
           rates_.still ? ex.kabschRotations[k] : unused[g]);
    if (!rates_.still)
      slot(nextRule_, ex.nextPositions, i, d.nextRotations[k], ex.nextFrames[k], d.nextNormals,
           ex.kabschRotations[k]);
  }
  fitSlots(jobs, jobCount, counts);
  for (int g = 0; g < count; ++g) finishVertex(d, vertices[g]);
}

void SurfaceGeometry::finishVertex(DynamicState& d, int i) const {
  const size_t k = static_cast<size_t>(i);
  ExtrinsicGeometry& ex = d.extrinsic;
  if (rates_.still) {
    d.nextRotations[k] = d.rotations[k];
    ex.nextFrames[k] = ex.frames[k];
    d.nextNormals.row(i) = ex.vertexNormals.row(i);
    ex.vertexAngularVelocities.row(i).setZero();
  } else {
    // ω_i: (F^t)ᵀ F^{t+h} = F̄ᵀ (U^tᵀ U^{t+h}) F̄, whose rotation vector is F̄ᵀ
    // times that of U^tᵀ U^{t+h}.
    const Vector3 restAxis =
        rates_.shared ? rates_.sharedAxis : rotationVector(d.rotations[k].conjugate() * d.nextRotations[k]);
    ex.vertexAngularVelocities.row(i) = (ex.restFrames[k].transpose() * restAxis * (1.0 / rates_.h)).transpose();
  }
  // p̈_i^t by the centred second difference.
  const double h = rates_.h, previousH = rates_.previousH;
  const double invH = 1.0 / h, invHSquared = 1.0 / (h * h), invPreviousH = 1.0 / previousH;
  const double secondDifferenceScale = 2.0 / (h + previousH);
  const RowVectors3& p0 = ex.previousPositions;
  const RowVectors3& p1 = ex.positions;
  const RowVectors3& p2 = ex.nextPositions;
  for (int c = 0; c < 3; ++c) {
    ex.vertexAccelerations(i, c) =
        previousH == h
            ? (p2(i, c) - 2.0 * p1(i, c) + p0(i, c)) * invHSquared
            : secondDifferenceScale * ((p2(i, c) - p1(i, c)) * invH - (p1(i, c) - p0(i, c)) * invPreviousH);
  }
}

void SurfaceGeometry::addCounts(const FitCounts& counts) {
  rotationFitStats_.fittedVertices += counts.fitted;
  rotationFitStats_.newtonIterations += counts.iterations;
  rotationFitStats_.svdFallbacks += counts.fallbacks;
}

template <typename VertexAt>
int SurfaceGeometry::prepareEach(int count, const VertexAt& vertexAt, FitCounts& total) {
  // Groups of kPrepareGroup list positions, the stale vertices of each fitted
  // together (prepareGroup), on the calling thread's OpenMP threads from
  // kMinParallelVertices on (threads::runLoop). A vertex's values depend on
  // its own slots only: the grouping and the threads change no bit. The
  // counts are integers, the same summed in any order.
  int prepared = 0;
  const int groups = (count + kPrepareGroup - 1) / kPrepareGroup;
  threads::runLoop(count >= kMinParallelVertices, [&] {
    FitCounts here;
    int preparedHere = 0;
#pragma omp for schedule(static) nowait
    for (int group = 0; group < groups; ++group) {
      int ids[kPrepareGroup];
      bool currentValid[kPrepareGroup];
      int stale = 0;
      for (int k = group * kPrepareGroup; k < std::min(count, (group + 1) * kPrepareGroup); ++k) {
        const int i = vertexAt(k);
        const unsigned stamp = preparedAt_[static_cast<size_t>(i)];
        if (stamp == refreshIndex_) continue;
        ids[stale] = i;
        currentValid[stale] = stamp + 1 == refreshIndex_;
        ++stale;
      }
      if (stale == 0) continue;
      prepareGroup(dynamic_, ids, currentValid, stale, here);
      for (int g = 0; g < stale; ++g) preparedAt_[static_cast<size_t>(ids[g])] = refreshIndex_;
      preparedHere += stale;
    }
#pragma omp critical(blot_threads_combine)
    {
      total.fitted += here.fitted;
      total.fallbacks += here.fallbacks;
      total.iterations += here.iterations;
      prepared += preparedHere;
    }
  });
  return prepared;
}

void SurfaceGeometry::prepareVertices(const int* vertices, int count) {
  const int n = topology_->vertexCount();
  for (int k = 0; k < count; ++k)
    if (vertices[k] < 0 || vertices[k] >= n)
      throw std::invalid_argument("SurfaceGeometry::prepareVertices: vertex " + std::to_string(vertices[k]) +
                                  " out of range [0, " + std::to_string(n) + ")");
  // In index order, each id once: a vertex's values depend on its own slot
  // only, so the order changes no bit, but neighbouring vertices then read
  // neighbouring memory in turn (the band lists its vertices ring by ring),
  // and the parallel loop never sees a repeat (two threads would write one
  // vertex). A list longer than #V has repeats: it goes in windows of #V ids,
  // one after the other.
  FitCounts total;
  for (int start = 0; start < count; start += n) {
    const int window = std::min(n, count - start);
    prepareOrder_.assign(vertices + start, vertices + start + window);  // capacity #V: no allocation
    std::sort(prepareOrder_.begin(), prepareOrder_.end());
    prepareOrder_.erase(std::unique(prepareOrder_.begin(), prepareOrder_.end()), prepareOrder_.end());
    const int* order = prepareOrder_.data();
    preparedCount_ += prepareEach(static_cast<int>(prepareOrder_.size()), [&](int k) { return order[k]; }, total);
  }
  addCounts(total);
}

void SurfaceGeometry::prepareAllVertices() {
  FitCounts total;
  preparedCount_ += prepareEach(topology_->vertexCount(), [](int i) { return i; }, total);
  addCounts(total);
}

SurfaceGeometry::DynamicState SurfaceGeometry::dynamicState() const {
  DynamicState d = dynamic_;
  const int n = topology_->vertexCount();
  FitCounts counts;
  int ids[kPrepareGroup];
  bool currentValid[kPrepareGroup];
  int stale = 0;
  for (int i = 0; i < n; ++i) {
    const unsigned stamp = preparedAt_[static_cast<size_t>(i)];
    if (stamp == refreshIndex_) continue;
    ids[stale] = i;
    currentValid[stale] = stamp + 1 == refreshIndex_;
    if (++stale == kPrepareGroup) {
      prepareGroup(d, ids, currentValid, stale, counts);
      stale = 0;
    }
  }
  if (stale > 0) prepareGroup(d, ids, currentValid, stale, counts);
  return d;
}

void SurfaceGeometry::restoreDynamicState(const DynamicState& s) {
  dynamic_ = s;
  kept_.valid = false;
  lastRefreshPartial_ = false;
  strainMeasured_ = false;  // measured again by the next test
  const ExtrinsicGeometry& ex = dynamic_.extrinsic;
  // A saved state has every vertex's values (dynamicState): only the t + h
  // slot's rule is needed for later refreshes.
  std::fill(preparedAt_.begin(), preparedAt_.end(), refreshIndex_);
  preparedCount_ = topology_->vertexCount();
  nextRule_ = SlotRule();
  if (s.nextSlotKind == static_cast<int>(SlotKind::Rigid) && !ex.kabschRotations.empty()) {
    nextRule_.kind = SlotKind::Rigid;
    nextRule_.rotation = dynamic_.nextRotations[0];
    nextRule_.matrix = ex.kabschRotations[0];
  } else if (s.nextSlotKind == static_cast<int>(SlotKind::Fitted)) {
    nextRule_.kind = SlotKind::Fitted;
  } else if (s.nextSlotKind != static_cast<int>(SlotKind::Rest)) {
    throw std::invalid_argument("SurfaceGeometry: nextSlotKind " + std::to_string(s.nextSlotKind) +
                                ", expected 0 (rest), 1 (rigid) or 2 (fitted)");
  }
  currentRule_ = nextRule_;  // every t slot is valid: never evaluated
  rates_ = RateRule();
  currentEqualsPrevious_ = ex.previousPositions == ex.positions;
  nextEqualsCurrent_ = ex.positions == ex.nextPositions;
}

FabricField isotropicFabricField(int faceCount, double densityDiffusivity, double viscosity) {
  if (faceCount < 1 || !(densityDiffusivity >= 0) || !(viscosity >= 0))
    throw std::invalid_argument("isotropicFabricField: need faceCount >= 1 and finite, non-negative coefficients");
  FabricField fabric;
  fabric.densityTensors = densityDiffusivity * identityFaceTensors(faceCount);
  fabric.velocityTensors = viscosity * identityFaceTensors(faceCount);
  fabric.weftDirections = RowVectors3::Zero(faceCount, 3);
  return fabric;
}

}  // namespace blot::stain
