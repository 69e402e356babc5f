#pragma once
/// P1 finite-element operators on a triangle mesh (paper sec. 3.2).
///
/// Sign convention: stiffness matrices are positive semidefinite, so implicit
/// diffusion reads (M + h L) σ^{t+h} = M σ^t. The paper's L_S is −L here.
///
/// Fabric tensors: per face, a symmetric 2x2 tensor S = [s_ww s_wp; s_wp s_pp]
/// expressed in the fabric basis (weft e, warp e⊥ = n × e), stored as one row
/// (s_ww, s_wp, s_pp) in m²/s; and a weft direction per face, a 3D vector
/// (any length; its projection onto the face plane is used). The tensor in the
/// face is S_T = (e, e⊥) S (e, e⊥)ᵀ.
#include <blot/stain/geometry/surface_topology.h>
#include <blot/stain/types.h>

#include <cstddef>
#include <vector>

namespace blot::stain {

/// The element kernel: 3x3 P1 stiffness K_kl = A ∇φ_k · S ∇φ_l of one triangle
/// with 2D corners p0, p1, p2 (any orientation) and a 2x2 SPD tensor S given in
/// the same 2D coordinates. Rows sum to zero; PSD for SPD S.
Matrix3 triangleStiffness(const Vector2& p0, const Vector2& p1, const Vector2& p2,
                          const Matrix2& tensor);

/// #F by 3 rows (1, 0, 1): the identity tensor on every face.
Eigen::MatrixX3d identityFaceTensors(int faceCount);

/// Anisotropic P1 stiffness L_ij = Σ_T ∫_T ∇φ_i · S_T ∇φ_j (#V by #V, symmetric
/// PSD for SPD tensors, rows sum to zero). faceTensors #F by 3, faceWeftDirections
/// #F by 3. With identity tensors this is the cotan Laplacian. Isotropic faces
/// (s_wp = 0, s_ww = s_pp) ignore their weft, which may then be zero; an
/// anisotropic face whose weft has no component in the face plane throws
/// std::invalid_argument naming the face (so does connectionLaplacian).
SparseMatrix anisotropicStiffness(const SurfaceTopology& topology,
                                  const RowVectors3& vertexPositions,
                                  const Eigen::MatrixX3d& faceTensors,
                                  const RowVectors3& faceWeftDirections);

/// Cotan Laplacian (#V by #V, PSD): L_ij = −w_ij, L_ii = Σ_j w_ij, assembled
/// from edge cotan weights (#E).
SparseMatrix cotanLaplacian(const SurfaceTopology& topology, const Vector& edgeCotanWeights);

/// Diagonal lumped mass matrix from vertex dual areas (#V).
SparseMatrix lumpedMassMatrix(const Vector& vertexDualAreas);

/// Anisotropic connection Laplacian (complex Hermitian #V by #V, PSD on any mesh).
///
/// Assembled per triangle as the Dirichlet energy, in the metric S_T, of the
/// linear interpolation of the three vertex vectors after transporting each into
/// the face frame (faceTransportAngles): with K^T the 3x3 P1 stiffness of the
/// triangle and r_k = exp(iφ_k), the triangle adds K^T_kl conj(r_k) r_l to entry
/// (v_k, v_l). Each triangle's block is unitarily similar to K^T, hence PSD,
/// whatever the sign of its cotan weights. (The edge-wise form Σ w_ij |u_i −
/// R_ij u_j|² is indefinite when weights are negative.)
ComplexSparseMatrix connectionLaplacian(const SurfaceTopology& topology,
                                        const RowVectors3& vertexPositions,
                                        const Eigen::MatrixX3d& faceTransportAngles,
                                        const Eigen::MatrixX3d& faceTensors,
                                        const RowVectors3& faceWeftDirections);

/// Where each face's 3x3 block lies in the value array of the operators above
/// on one topology (they all have the same compressed pattern: each vertex of
/// a face and its edge neighbours): entry (faces(f, k), faces(f, l)) is value
/// index[9 f + 3 k + l]. Lets a rebuild refill an operator in place.
struct OneRingEntries {
  std::vector<int> index;     ///< 9 #F value positions
  Eigen::Index nonZeros = 0;  ///< entries of the pattern

  /// Whether the refills below can write L with this table on `topology`
  /// (they throw otherwise): L is #V x #V, compressed, with the pattern's
  /// entry count, and the table is of this topology's faces.
  template <typename Scalar>
  bool fits(const SurfaceTopology& topology, const Eigen::SparseMatrix<Scalar>& L) const {
    const Eigen::Index n = topology.vertexCount();
    return index.size() == 9 * static_cast<size_t>(topology.faceCount()) && L.rows() == n && L.cols() == n &&
           L.isCompressed() && L.nonZeros() == nonZeros;
  }
};
OneRingEntries oneRingFaceEntries(const SurfaceTopology& topology);
/// anisotropicStiffness and connectionLaplacian written into L's values
/// instead of a new matrix: L must hold an operator built by them (or the
/// FromLengths ones below) on the same topology, and entries =
/// oneRingFaceEntries(topology). The values are bitwise those of a new
/// assembly from the same inputs (the same terms summed in the same order);
/// nothing is allocated. A matrix or table of another size throws
/// std::invalid_argument.
void refillAnisotropicStiffness(const SurfaceTopology& topology, const RowVectors3& vertexPositions,
                                const Eigen::MatrixX3d& faceTensors, const RowVectors3& faceWeftDirections,
                                const OneRingEntries& entries, SparseMatrix& L);
void refillConnectionLaplacian(const SurfaceTopology& topology, const RowVectors3& vertexPositions,
                               const Eigen::MatrixX3d& faceTransportAngles, const Eigen::MatrixX3d& faceTensors,
                               const RowVectors3& faceWeftDirections, const OneRingEntries& entries,
                               ComplexSparseMatrix& L);
/// The same operators from edge lengths alone (the intrinsic tier of
/// SurfaceGeometry): face f is laid out in 2D from its lengths ℓ(faceEdges(f,
/// 0..2)) (corner 0 at the origin, corner 1 on +x, corner 2 above), and its
/// weft is a c₁ + b c₂ with (a, b) = faceWeftCoefficients row f and c₁, c₂
/// the laid-out edges from corner 0: the rest weft carried as a material
/// line. Equal to the position-based functions up to rounding on the same
/// shape. An anisotropic face whose weft has no length throws
/// std::invalid_argument naming the face.
SparseMatrix anisotropicStiffnessFromLengths(const SurfaceTopology& topology, const Vector& edgeLengths,
                                             const Eigen::MatrixX3d& faceTensors,
                                             const Eigen::MatrixX2d& faceWeftCoefficients);
ComplexSparseMatrix connectionLaplacianFromLengths(const SurfaceTopology& topology, const Vector& edgeLengths,
                                                   const Eigen::MatrixX3d& faceTransportAngles,
                                                   const Eigen::MatrixX3d& faceTensors,
                                                   const Eigen::MatrixX2d& faceWeftCoefficients);
/// Both from lengths into existing one-ring patterns (what SurfaceGeometry's
/// whole rebuild does), each face laid out once: `stiffness` gets
/// anisotropicStiffnessFromLengths's values with densityTensors,
/// `connection` connectionLaplacianFromLengths's with velocityTensors,
/// bitwise. `faceAreas` are those lengths' faceAreas (their Heron areas,
/// not computed again). Allocates nothing; a matrix, table or area vector of
/// another topology throws std::invalid_argument.
void refillStiffnessAndConnectionFromLengths(const SurfaceTopology& topology, const Vector& edgeLengths,
                                             const Vector& faceAreas, const Eigen::MatrixX3d& densityTensors,
                                             const Eigen::MatrixX3d& faceTransportAngles,
                                             const Eigen::MatrixX3d& velocityTensors,
                                             const Eigen::MatrixX2d& faceWeftCoefficients,
                                             const OneRingEntries& entries, SparseMatrix& stiffness,
                                             ComplexSparseMatrix& connection);
/// Partial re-assembly into L's existing pattern (a matrix built by the
/// function above on the same topology): every entry (i, j) with both
/// vertexMarks[i] and vertexMarks[j] set is summed again from zero over
/// faces[0, faceCount), which must list, ascending, every face with a marked
/// vertex; the other entries are kept. `vertices` lists the marked vertices.
/// The entries come out bitwise as a whole assembly from the same inputs
/// gives them (same terms, same order). Allocates nothing. With `entries`
/// (oneRingFaceEntries of this topology, fitting L) each entry's position is
/// read from the table instead of searched for in its column.
void reassembleStiffnessFromLengths(const SurfaceTopology& topology, const Vector& edgeLengths,
                                    const Eigen::MatrixX3d& faceTensors, const Eigen::MatrixX2d& faceWeftCoefficients,
                                    const char* vertexMarks, const int* vertices, int vertexCount, const int* faces,
                                    int faceCount, SparseMatrix& L, const OneRingEntries* entries = nullptr);
void reassembleConnectionFromLengths(const SurfaceTopology& topology, const Vector& edgeLengths,
                                     const Eigen::MatrixX3d& faceTransportAngles, const Eigen::MatrixX3d& faceTensors,
                                     const Eigen::MatrixX2d& faceWeftCoefficients, const char* vertexMarks,
                                     const int* vertices, int vertexCount, const int* faces, int faceCount,
                                     ComplexSparseMatrix& L, const OneRingEntries* entries = nullptr);
/// #F by 2: the weft of each face (faceWeftDirections, rest shape) as
/// a ē₁ + b ē₂ of its rest edges from corner 0 (least squares: the weft's
/// projection onto the face plane). Rows whose in-plane weft is zero (or
/// shorter than 1e-12 of the weft) are NaN, which only anisotropic faces
/// reject (at assembly).
Eigen::MatrixX2d faceWeftCoefficients(const SurfaceTopology& topology, const RowVectors3& restPositions,
                                      const RowVectors3& faceWeftDirections);

/// The real 2#V by 2#V form of a complex Hermitian matrix: entry a + ib becomes
/// the block [a −b; b a] (vector (x, y) of vertex i at rows 2i, 2i+1).
SparseMatrix realForm(const ComplexSparseMatrix& complexMatrix);

}  // namespace blot::stain
