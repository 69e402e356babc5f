#pragma once
/// A flag waving in z, for stain tests on a deforming surface: a
/// non-isometric motion, so the strain test trips now and then.
#include <blot/stain/geometry/triangle_mesh.h>

#include <cmath>

namespace blot::stain {

/// Positions (#V by 3, m) at time t (s) of `rest` (a flat mesh in z = 0)
/// waving: z = 0.05 x sin(6x − 4t)(1 + 0.3 y).
inline RowVectors3 wavingPositions(const TriangleMesh& rest, double t) {
  RowVectors3 p = rest.vertexPositions;
  for (int i = 0; i < p.rows(); ++i) {
    const double x = rest.vertexPositions(i, 0), y = rest.vertexPositions(i, 1);
    p(i, 2) = 0.05 * x * std::sin(6.0 * x - 4.0 * t) * (1.0 + 0.3 * y);
  }
  return p;
}

}  // namespace blot::stain
