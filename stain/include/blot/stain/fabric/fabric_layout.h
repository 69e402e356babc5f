#pragma once
/// Fabric laid out on a mesh (paper sec. 3.2, first and last paragraphs): the
/// surface is split into patches of triangles, each with one material (a weave
/// pattern, homogenized, or a tensor given directly) and a smooth weft
/// direction field from the vector Laplace equation with user constraints.
/// The result is the per-face input of anisotropicStiffness and
/// connectionLaplacian (operators.h).
#include <blot/stain/fabric/homogenization.h>
#include <blot/stain/geometry/surface_topology.h>
#include <blot/stain/types.h>
#include <blot/stain/fabric/weave_pattern.h>

#include <functional>
#include <optional>
#include <stdexcept>
#include <string>
#include <vector>

namespace blot::stain {

/// Input-data error (tier b) in a fabric layout: names the patch and the face.
class FabricLayoutError : public std::runtime_error {
 public:
  using std::runtime_error::runtime_error;
};

/// The weft runs along `direction` (3D, any length, metres-free; its projection
/// onto the face plane is used) on face `face` (index into the whole mesh).
struct WeftConstraint {
  int face = -1;
  Vector3 direction = Vector3::UnitX();
};

/// One patch: its faces, its material and at least one weft constraint.
struct FabricPatch {
  std::string name = "patch";       ///< Used in error messages.
  std::vector<int> faces;           ///< Face indices of the whole mesh (any order, no repeats).
  /// Weave pattern to homogenize; when empty, `tensor` is used as given.
  std::optional<WeavePattern> pattern;
  /// Tensor in the (weft, warp) basis, m²/s, SPD; used only without a pattern.
  Matrix2 tensor = Matrix2::Identity();
  /// At least one per connected piece of the patch; all on faces of the patch.
  std::vector<WeftConstraint> weftConstraints;
  /// The constraints are one weft direction held on every face (a scene's
  /// "weft"): errors then name that direction, not a constraint the caller
  /// never wrote.
  bool oneWeftDirection = false;
};

/// Per-face fabric of the whole mesh, ready for anisotropicStiffness.
struct FabricLayout {
  Eigen::MatrixX3d faceTensors;      ///< #F by 3 rows (s_ww, s_wp, s_pp), m²/s, weft/warp basis.
  RowVectors3 faceWeftDirections;    ///< #F by 3 unit weft directions in each face's plane.
  std::vector<int> facePatches;      ///< #F index of each face's patch.
  std::vector<Matrix2> patchTensors; ///< Per patch: S_eff of its pattern, or its direct tensor.
};

/// Faces whose label equals `label` (ascending), e.g. TriangleMesh::faceLabels.
std::vector<int> facesWithLabel(const std::vector<int>& faceLabels, int label);

/// Faces whose centroid (metres) satisfies `rule` (ascending): patches from a
/// rule in a scene, e.g. "x < 0.5".
std::vector<int> facesWhere(const SurfaceTopology& topology, const RowVectors3& vertexPositions,
                            const std::function<bool(const Vector3& centroid)>& rule);

/// Smooth weft field of one patch: the discrete vector Laplace equation
/// (isotropic connection Laplacian of the patch's own sub-mesh, so the patch
/// border is a free boundary) with the constrained faces' corner vectors held
/// fixed, solved with CHOLMOD; per face, the corner vectors carried into the
/// face frame are averaged and normalised. Returns #faces by 3 unit vectors in
/// the order of `faces`. On a flat patch with one constraint the field is
/// exactly constant. Throws FabricLayoutError (no constraint in a connected
/// piece, constraint on a foreign face, direction normal to its face, faces
/// not forming a manifold). oneWeftDirection: the constraints are one
/// direction on every face (FabricPatch::oneWeftDirection), as errors say.
RowVectors3 patchWeftField(const SurfaceTopology& topology, const RowVectors3& vertexPositions,
                           const std::vector<int>& faces, const std::vector<WeftConstraint>& constraints,
                           const std::string& patchName = "patch", bool oneWeftDirection = false);

/// Lays out all patches: every face must belong to exactly one patch. Patterns
/// are homogenized through `homogenizer` (cached by content) with
/// `subdivisions` squares per cell side. Throws FabricLayoutError naming the
/// patch and face on bad input, PatternError never (patterns are already valid).
FabricLayout fabricLayout(const SurfaceTopology& topology, const RowVectors3& vertexPositions,
                          const std::vector<FabricPatch>& patches, Homogenizer& homogenizer,
                          int subdivisions = kAutoSubdivisions);

}  // namespace blot::stain
