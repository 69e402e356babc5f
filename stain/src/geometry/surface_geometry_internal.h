#pragma once
// What the files of SurfaceGeometry share and no other code needs.
#include <blot/stain/types.h>

#include <algorithm>
#include <cmath>

namespace blot::stain::detail {

// Vertices prepared together (prepareGroup): their fits, up to two each,
// fill the lanes of fitRotations.
constexpr int kPrepareGroup = 4;
// Below this many vertices a refresh takes a few microseconds and waking a
// second thread costs more than it saves (and much more on a loaded machine).
constexpr int kMinParallelVertices = 2048;

// max_e |ℓ_e/ℓ̂_e − 1| from the extremes of the squared ratios ℓ_e²/ℓ̂_e²
// over the measured edges (1 and 1 for none): the strain tests' one root each.
inline double strainFromSquaredRatios(double maxRatio, double minRatio) {
  return std::max(std::sqrt(maxRatio) - 1.0, 1.0 - std::sqrt(minRatio));
}

// Rotation vector (axis × angle, angle in [0, π]) of a unit quaternion
// q = (cos θ/2, sin θ/2 a): θ a = v · 2 atan(x)/(x w), x = |v|/w (w ≥ 0). For
// x² < 1e-3 (θ < 0.063 rad, the usual per-step rotation) atan(x)/x is its
// series to x¹⁰, truncation x¹²/13 < 1e-19: no square root, division or atan2.
inline Vector3 rotationVector(const Eigen::Quaterniond& q) {
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

}  // namespace blot::stain::detail
