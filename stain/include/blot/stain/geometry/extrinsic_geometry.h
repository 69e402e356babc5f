#pragma once
/// Extrinsic geometry: quantities that depend on the embedding and change
/// every step as the cloth moves (normals, tangent frames).
#include <blot/stain/geometry/surface_topology.h>
#include <blot/stain/types.h>

namespace blot::stain {

/// #F unit face normals (right-hand rule over faces(f, 0..2)).
RowVectors3 faceNormals(const SurfaceTopology& topology, const RowVectors3& vertexPositions);

/// #V unit vertex normals: area-weighted average of incident face normals
/// (the sum of unnormalised cross products), normalised.
RowVectors3 vertexNormals(const SurfaceTopology& topology, const RowVectors3& vertexPositions);

/// Per-vertex tangent frames F_i = [x_i y_i z_i] as in the paper (sec. 3.1):
/// z_i the vertex normal, y_i = z_i × e / |z_i × e| with e the vertex's reference
/// edge (to the first one-ring neighbour, SurfaceTopology::ringNeighbors), and
/// x_i = y_i × z_i, i.e. the reference edge projected to the tangent plane.
/// So the polar-map angle α of the reference edge is 0 in the vertex frame.
struct VertexFrames {
  RowVectors3 xAxes;  ///< #V by 3, unit.
  RowVectors3 yAxes;  ///< #V by 3, unit.
  RowVectors3 zAxes;  ///< #V by 3, unit (= vertex normals).
  /// 3x3 frame of vertex i with columns x, y, z.
  Matrix3 frame(int i) const;
};

VertexFrames vertexTangentFrames(const SurfaceTopology& topology,
                                 const RowVectors3& vertexPositions,
                                 const RowVectors3& vertexNormals);

}  // namespace blot::stain
