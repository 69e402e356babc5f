// The SO(3) rotation fits: Kabsch by SVD, Newton on SO(3), and the batch
// fit in SIMD lanes behind SurfaceGeometry's vertex frames.
//
// Design note: docs/design-notes.md, "stain/src/geometry/surface_geometry.cpp".
#include <blot/stain/geometry/rotation_fit.h>

#include <Eigen/SVD>

#include <algorithm>
#include <cmath>
#include <stdexcept>

#include "numerics/lanes.h"

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
// A Newton step longer than this (rad) means the start was far off: use the SVD.
constexpr double kMaxNewtonStep = 1.0;
// Relative size of a Hessian pivot below which the fit is treated as degenerate.
constexpr double kPivotTolerance = 1e-10;

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

void fitRotations(RotationFitJob* jobs, int count, const std::vector<Matrix3>& restFrames, RotationFitMethod method,
                  RotationFitStats& counts) {
  // The slot's normal once its frame is written: n / |n| (unit), or, where a
  // fully folded fan has none, the fitted frame's.
  const auto setNormal = [](RotationFitJob& job, const double (&unit)[3]) {
    for (int c = 0; c < 3; ++c)
      (*job.normals)(job.vertex, c) = job.normalSquared > 0.0 ? unit[c] : (*job.frame)(c, 2);
  };
  const auto finish = [&](RotationFitJob& job, const Eigen::Quaterniond& q, const Matrix3& U) {
    *job.rotation = q;
    *job.fit = U;
    job.frame->noalias() = U * restFrames[static_cast<size_t>(job.vertex)];
    double unit[3] = {0.0, 0.0, 0.0};
    if (job.normalSquared > 0.0) {
      const double inverse = 1.0 / std::sqrt(job.normalSquared);
      for (int c = 0; c < 3; ++c) unit[c] = job.normal(c) * inverse;
    }
    setNormal(job, unit);
    ++counts.fittedVertices;
  };
  if (method == RotationFitMethod::Svd) {
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
      const RotationFitJob& job = jobs[start + std::min(l, used - 1)];
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
      RotationFitJob& job = jobs[start + l];
      counts.newtonIterations += iterations[l];
      if (status[l] != LaneStatus::Converged) {
        ++counts.svdFallbacks;
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
      ++counts.fittedVertices;
    }
  }
}

}  // namespace blot::stain
