#pragma once
/// A triangle mesh as loaded from a file or built in code: positions and
/// triangles, plus optional per-face labels (fabric patches) and per-vertex UVs.
#include <blot/stain/types.h>

#include <stdexcept>
#include <string>
#include <vector>

namespace blot::stain {

struct TriangleMesh {
  RowVectors3 vertexPositions;  ///< #V by 3, metres.
  Triangles faces;              ///< #F by 3, counter-clockwise (outward normal by right-hand rule).
  std::vector<int> faceLabels;  ///< #F patch labels, or empty when the file has none.
  Eigen::MatrixX2d vertexUVs;   ///< #V by 2 texture coordinates, or 0 rows when absent.
};

/// Input-data error (tier b): names the file and the offending element or line.
class MeshError : public std::runtime_error {
 public:
  using std::runtime_error::runtime_error;
};

}  // namespace blot::stain
