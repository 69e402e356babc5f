// Fabric on the mesh: patches, weft fields, per-face tensors (paper sec. 3.2).
//
// Design note: docs/design-notes.md, "stain/src/fabric/fabric_layout.cpp".
#include <blot/stain/fabric/fabric_layout.h>

#include <blot/stain/geometry/intrinsic_geometry.h>
#include <blot/stain/geometry/operators.h>
#include <blot/stain/numerics/sparse_solver.h>
#include <blot/stain/geometry/transport.h>
#include <blot/stain/geometry/triangle_mesh.h>

#include <cmath>
#include <numeric>
#include <sstream>

namespace blot::stain {

namespace {

/// Face frame of operators.h / transport.h: x along v0 -> v1, y = n × x.
struct FaceFrame {
  Vector3 x, y, n;
};

FaceFrame faceFrame(const RowVectors3& positions, const Triangles& faces, int f) {
  const Vector3 p0 = positions.row(faces(f, 0)).transpose();
  const Vector3 e1 = positions.row(faces(f, 1)).transpose() - p0;
  const Vector3 e2 = positions.row(faces(f, 2)).transpose() - p0;
  FaceFrame frame;
  frame.x = e1.normalized();
  frame.n = e1.cross(e2).normalized();
  frame.y = frame.n.cross(frame.x);
  return frame;
}

std::string vectorText(const Vector3& v) {
  std::ostringstream s;
  s << "(" << v.x() << ", " << v.y() << ", " << v.z() << ")";
  return s.str();
}

/// Union-find root with path halving.
int findRoot(std::vector<int>& parent, int v) {
  while (parent[static_cast<size_t>(v)] != v) {
    parent[static_cast<size_t>(v)] = parent[static_cast<size_t>(parent[static_cast<size_t>(v)])];
    v = parent[static_cast<size_t>(v)];
  }
  return v;
}

}  // namespace

std::vector<int> facesWithLabel(const std::vector<int>& faceLabels, int label) {
  std::vector<int> faces;
  for (size_t f = 0; f < faceLabels.size(); ++f)
    if (faceLabels[f] == label) faces.push_back(static_cast<int>(f));
  return faces;
}

std::vector<int> facesWhere(const SurfaceTopology& topology, const RowVectors3& vertexPositions,
                            const std::function<bool(const Vector3& centroid)>& rule) {
  std::vector<int> faces;
  const Triangles& all = topology.faces();
  for (int f = 0; f < topology.faceCount(); ++f) {
    const Vector3 centroid = (vertexPositions.row(all(f, 0)) + vertexPositions.row(all(f, 1)) +
                              vertexPositions.row(all(f, 2))).transpose() / 3.0;
    if (rule(centroid)) faces.push_back(f);
  }
  return faces;
}

RowVectors3 patchWeftField(const SurfaceTopology& topology, const RowVectors3& vertexPositions,
                           const std::vector<int>& faces, const std::vector<WeftConstraint>& constraints,
                           const std::string& patchName, bool oneWeftDirection) {
  const std::string where = "patch \"" + patchName + "\"";
  if (faces.empty()) throw FabricLayoutError(where + ": has no faces");
  if (constraints.empty()) throw FabricLayoutError(where + ": needs at least one weft constraint");

  // The patch's own sub-mesh: local vertex ids in order of first appearance.
  const Triangles& allFaces = topology.faces();
  std::vector<int> localVertex(static_cast<size_t>(topology.vertexCount()), -1);
  std::vector<int> localFace(static_cast<size_t>(topology.faceCount()), -1);
  std::vector<int> globalVertex;
  Triangles patchFaces(static_cast<Eigen::Index>(faces.size()), 3);
  for (size_t lf = 0; lf < faces.size(); ++lf) {
    const int f = faces[lf];
    if (f < 0 || f >= topology.faceCount())
      throw FabricLayoutError(where + ": face " + std::to_string(f) + " out of range [0, " +
                              std::to_string(topology.faceCount()) + ")");
    if (localFace[static_cast<size_t>(f)] >= 0)
      throw FabricLayoutError(where + ": face " + std::to_string(f) + " listed twice");
    localFace[static_cast<size_t>(f)] = static_cast<int>(lf);
    for (int k = 0; k < 3; ++k) {
      int& local = localVertex[static_cast<size_t>(allFaces(f, k))];
      if (local < 0) {
        local = static_cast<int>(globalVertex.size());
        globalVertex.push_back(allFaces(f, k));
      }
      patchFaces(static_cast<Eigen::Index>(lf), k) = local;
    }
  }
  const int vertexCount = static_cast<int>(globalVertex.size());
  RowVectors3 positions(vertexCount, 3);
  for (int v = 0; v < vertexCount; ++v) positions.row(v) = vertexPositions.row(globalVertex[static_cast<size_t>(v)]);

  std::optional<SurfaceTopology> patch;
  try {
    patch.emplace(patchFaces, vertexCount, where);
  } catch (const MeshError& e) {
    throw FabricLayoutError(where + ": its faces do not form a manifold surface: " + e.what());
  }
  const Eigen::MatrixX3d cornerAngles = faceCornerAngles(*patch, edgeLengths(*patch, positions));
  const Eigen::MatrixX3d transport = faceTransportAngles(*patch, cornerAngles, geodesicPolarMap(*patch, cornerAngles));
  const int faceCount = patch->faceCount();

  // Constraint values per vertex, in the vertex frames: u_v = conj(r_k) u_face.
  ComplexVector fixedSum = ComplexVector::Zero(vertexCount);
  std::vector<int> fixedCount(static_cast<size_t>(vertexCount), 0);
  for (size_t c = 0; c < constraints.size(); ++c) {
    const WeftConstraint& constraint = constraints[c];
    const std::string which = where + (oneWeftDirection ? ": weft" : ": weft_constraints[" + std::to_string(c) + "]");
    const std::string face = "face " + std::to_string(constraint.face);
    if (constraint.face < 0 || constraint.face >= topology.faceCount() ||
        localFace[static_cast<size_t>(constraint.face)] < 0)
      throw FabricLayoutError(which + ": " + face + " is not part of the patch");
    const int lf = localFace[static_cast<size_t>(constraint.face)];
    const FaceFrame frame = faceFrame(positions, patchFaces, lf);
    const Vector3 inPlane = constraint.direction - constraint.direction.dot(frame.n) * frame.n;
    if (!constraint.direction.allFinite() || !(inPlane.norm() > 1e-9 * constraint.direction.norm()))
      throw FabricLayoutError(which + ": direction " + vectorText(constraint.direction) +
                              " has no component in the plane of " + face + " (normal " + vectorText(frame.n) +
                              "): expected a direction along the cloth");
    const Complex faceValue = std::polar(1.0, std::atan2(inPlane.dot(frame.y), inPlane.dot(frame.x)));
    for (int k = 0; k < 3; ++k) {
      const int v = patchFaces(lf, k);
      fixedSum(v) += std::conj(std::polar(1.0, transport(lf, k))) * faceValue;
      ++fixedCount[static_cast<size_t>(v)];
    }
  }
  std::vector<char> isFixed(static_cast<size_t>(vertexCount), 0);
  ComplexVector fixedValue = ComplexVector::Zero(vertexCount);
  for (int v = 0; v < vertexCount; ++v) {
    if (fixedCount[static_cast<size_t>(v)] == 0) continue;
    const double length = std::abs(fixedSum(v));
    if (!(length > 1e-6 * fixedCount[static_cast<size_t>(v)]))
      throw FabricLayoutError(where + ": weft constraints cancel at mesh vertex " +
                              std::to_string(globalVertex[static_cast<size_t>(v)]) +
                              " (opposite directions on neighbouring faces)");
    isFixed[static_cast<size_t>(v)] = 1;
    fixedValue(v) = fixedSum(v) / length;
  }

  // Every connected piece (faces sharing a vertex) needs a fixed vertex, or the
  // system is singular (the parallel fields of that piece are undetermined).
  std::vector<int> parent(static_cast<size_t>(vertexCount));
  std::iota(parent.begin(), parent.end(), 0);
  for (int lf = 0; lf < faceCount; ++lf)
    for (int k = 1; k < 3; ++k)
      parent[static_cast<size_t>(findRoot(parent, patchFaces(lf, k)))] = findRoot(parent, patchFaces(lf, 0));
  std::vector<char> rootFixed(static_cast<size_t>(vertexCount), 0);
  for (int v = 0; v < vertexCount; ++v)
    if (isFixed[static_cast<size_t>(v)]) rootFixed[static_cast<size_t>(findRoot(parent, v))] = 1;
  for (int lf = 0; lf < faceCount; ++lf)
    if (!rootFixed[static_cast<size_t>(findRoot(parent, patchFaces(lf, 0)))])
      throw FabricLayoutError(where + ": the connected piece containing face " +
                              std::to_string(faces[static_cast<size_t>(lf)]) + " has no weft constraint");

  // Vector Laplace equation with Dirichlet rows: free rows keep L, fixed
  // columns move to the right-hand side, fixed rows become identity.
  const ComplexSparseMatrix laplacian = connectionLaplacian(
      *patch, positions, transport, identityFaceTensors(faceCount), RowVectors3::Zero(faceCount, 3));
  std::vector<Eigen::Triplet<Complex>> triplets;
  triplets.reserve(static_cast<size_t>(laplacian.nonZeros()));
  ComplexVector rhs = ComplexVector::Zero(vertexCount);
  for (int col = 0; col < laplacian.outerSize(); ++col) {
    for (ComplexSparseMatrix::InnerIterator it(laplacian, col); it; ++it) {
      const int row = static_cast<int>(it.row());
      const bool rowFixed = isFixed[static_cast<size_t>(row)] != 0;
      const bool colFixed = isFixed[static_cast<size_t>(col)] != 0;
      if (!rowFixed && !colFixed) triplets.emplace_back(row, col, it.value());
      if (!rowFixed && colFixed) rhs(row) -= it.value() * fixedValue(col);
    }
  }
  for (int v = 0; v < vertexCount; ++v) {
    if (!isFixed[static_cast<size_t>(v)]) continue;
    triplets.emplace_back(v, v, Complex(1.0, 0.0));
    rhs(v) = fixedValue(v);
  }
  ComplexSparseMatrix system(vertexCount, vertexCount);
  system.setFromTriplets(triplets.begin(), triplets.end());
  ComplexCholeskySolver solver;
  ComplexVector field;
  SolverStatus status = solver.compute(system);
  if (status == SolverStatus::Ok) status = solver.solve(rhs, field);
  if (status != SolverStatus::Ok)
    throw FabricLayoutError(where + ": weft field solve failed (" + toString(status) + ")");

  // Per face: corner vectors carried into the face frame, averaged, normalised.
  RowVectors3 weft(faceCount, 3);
  for (int lf = 0; lf < faceCount; ++lf) {
    Complex sum(0.0, 0.0), largest(0.0, 0.0);
    double magnitudes = 0.0;
    for (int k = 0; k < 3; ++k) {
      const Complex inFace = std::polar(1.0, transport(lf, k)) * field(patchFaces(lf, k));
      sum += inFace;
      magnitudes += std::abs(inFace);
      if (std::abs(inFace) > std::abs(largest)) largest = inFace;
    }
    // Near a singularity of the field the corners can cancel; the largest
    // corner vector still gives a direction (the field is smooth elsewhere).
    const Complex direction = std::abs(sum) > 1e-9 * magnitudes ? sum : largest;
    if (!(std::abs(direction) > 0.0))
      throw FabricLayoutError(where + ": weft field vanishes on face " + std::to_string(faces[static_cast<size_t>(lf)]));
    const FaceFrame frame = faceFrame(positions, patchFaces, lf);
    const Complex unit = direction / std::abs(direction);
    weft.row(lf) = (unit.real() * frame.x + unit.imag() * frame.y).transpose();
  }
  return weft;
}

FabricLayout fabricLayout(const SurfaceTopology& topology, const RowVectors3& vertexPositions,
                          const std::vector<FabricPatch>& patches, Homogenizer& homogenizer, int subdivisions) {
  const int faceCount = topology.faceCount();
  FabricLayout layout;
  layout.faceTensors.resize(faceCount, 3);
  layout.faceWeftDirections.resize(faceCount, 3);
  layout.facePatches.assign(static_cast<size_t>(faceCount), -1);
  layout.patchTensors.reserve(patches.size());
  for (size_t p = 0; p < patches.size(); ++p) {
    const FabricPatch& patch = patches[p];
    const std::string where = "patch \"" + patch.name + "\"";
    for (int f : patch.faces) {
      if (f < 0 || f >= faceCount)
        throw FabricLayoutError(where + ": face " + std::to_string(f) + " out of range [0, " +
                                std::to_string(faceCount) + ")");
      const int previous = layout.facePatches[static_cast<size_t>(f)];
      if (previous >= 0)
        throw FabricLayoutError(where + ": face " + std::to_string(f) + " already belongs to patch \"" +
                                patches[static_cast<size_t>(previous)].name + "\"");
      layout.facePatches[static_cast<size_t>(f)] = static_cast<int>(p);
    }
    Matrix2 tensor = patch.tensor;
    if (patch.pattern) {
      tensor = homogenizer.homogenize(*patch.pattern, subdivisions).effective;
    } else {
      const double det = tensor(0, 0) * tensor(1, 1) - tensor(0, 1) * tensor(1, 0);
      if (!tensor.allFinite() || std::abs(tensor(0, 1) - tensor(1, 0)) > 1e-9 * tensor.cwiseAbs().maxCoeff() ||
          !(tensor(0, 0) > 0.0) || !(det > 0.0))
        throw FabricLayoutError(where + ": tensor must be symmetric positive definite");
    }
    layout.patchTensors.push_back(tensor);
    const RowVectors3 weft = patchWeftField(topology, vertexPositions, patch.faces, patch.weftConstraints, patch.name,
                                            patch.oneWeftDirection);
    for (size_t i = 0; i < patch.faces.size(); ++i) {
      const int f = patch.faces[i];
      layout.faceWeftDirections.row(f) = weft.row(static_cast<Eigen::Index>(i));
      layout.faceTensors.row(f) << tensor(0, 0), 0.5 * (tensor(0, 1) + tensor(1, 0)), tensor(1, 1);
    }
  }
  for (int f = 0; f < faceCount; ++f)
    if (layout.facePatches[static_cast<size_t>(f)] < 0)
      throw FabricLayoutError("face " + std::to_string(f) + " belongs to no fabric patch");
  return layout;
}

}  // namespace blot::stain
