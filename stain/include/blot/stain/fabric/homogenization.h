#pragma once
/// Homogenization of a weave pattern into one effective (bulk) diffusion tensor
/// (paper sec. 2, eqs. 1-2), plus the classical bounds it must lie between.
///
/// All tensors are 2x2, symmetric, in the pattern's (x, y) = (weft, warp) basis
/// and the pattern's diffusion units (m²/s in the engine). S_eff does not depend
/// on the physical cell size, so the tile is meshed with unit cells.
#include <blot/stain/types.h>
#include <blot/stain/fabric/weave_pattern.h>

#include <cstdint>
#include <map>
#include <utility>
#include <vector>

namespace blot::stain {

/// Passed as `subdivisions`: choose K with defaultSubdivisions(pattern).
inline constexpr int kAutoSubdivisions = 0;

/// The default K (squares per cell side) for a pattern: the largest even K in
/// [4, 32] with rows·cols·K² <= 16384 unknowns, and 4 for tiles larger than
/// 32x32 cells. From the convergence study in docs/patterns.md: the error of
/// S_eff decays like K^-1.9 for the woven presets (0.2% at K = 4) and like
/// K^-1 to K^-1.3 where neighbouring cells differ by ~60:1 or more (rib knit:
/// 2.7% at K = 4, 0.6% at K = 16), while the cost is one sparse Cholesky of
/// rows·cols·K² unknowns. A fixed K would either waste time on large tiles or
/// accuracy on small ones; the budget keeps every default solve at about
/// 16K unknowns (a 32x32-cell tile gets K = 4, the 4x8 rib knit K = 22, the
/// 4x4 plain weave K = 32).
int defaultSubdivisions(const WeavePattern& pattern);

/// Everything `blot homogenize` reports about one pattern.
struct HomogenizationResult {
  Matrix2 effective;    ///< S_eff of eq. (1), symmetrised (asymmetry is solver round-off).
  Matrix2 average;      ///< Plain cell average ⟨S⟩ (the paper's "direct average"; equals the Voigt bound).
  Matrix2 reussBound;   ///< Harmonic bound ⟨S⁻¹⟩⁻¹: S_eff − reussBound is PSD.
  Matrix2 voigtBound;   ///< Arithmetic bound ⟨S⟩: voigtBound − S_eff is PSD.
  Vector2 eigenvalues;  ///< Of `effective`, ascending (min, max).
  /// Angle from the weft (x) axis to the eigenvector of the largest eigenvalue,
  /// counter-clockwise, in radians, in (−π/2, π/2]; 0 when isotropic.
  double principalAngle = 0.0;
  int subdivisions = 0;          ///< K used.
  std::uint64_t patternHash = 0; ///< WeavePattern::contentHash() of the input.
  int vertexCount = 0;           ///< Vertices of the torus mesh (rows·K · cols·K).
};

/// Harmonic (Reuss) bound ⟨S⁻¹⟩⁻¹ over the tile's cells (equal areas).
Matrix2 reussBound(const WeavePattern& pattern);
/// Arithmetic (Voigt) bound ⟨S⟩ over the tile's cells (equal areas).
Matrix2 voigtBound(const WeavePattern& pattern);

/// Eigenvalues (ascending) of a symmetric 2x2 tensor, closed form.
Vector2 symmetricEigenvalues(const Matrix2& tensor);
/// Angle (radians, in (−π/2, π/2]) from the x axis to the eigenvector of the
/// largest eigenvalue of a symmetric 2x2 tensor; 0 when the eigenvalues agree.
double principalAngle(const Matrix2& tensor);

/// Solves the two periodic cell problems ∇·S(∇f_i + e_i) = 0 with P1 elements on
/// a torus mesh of the tile (each cell K x K squares, each square two triangles
/// with alternating diagonals), CHOLMOD on the system with one vertex pinned,
/// and evaluates S_eff by eq. (1). `subdivisions` (K) >= 1, or kAutoSubdivisions. Cost: one sparse
/// Cholesky of size rows·cols·K². Throws std::runtime_error if the solver fails
/// (it cannot for a valid pattern).
HomogenizationResult homogenize(const WeavePattern& pattern,
                                int subdivisions = kAutoSubdivisions);

/// Homogenizes with a cache keyed by pattern content and K, so a pattern used by
/// several patches or scenes is solved once. Owns its cache; not thread-safe.
class Homogenizer {
 public:
  /// The result for (pattern, subdivisions), computed on first request; the key
  /// uses the resolved K, so auto and the explicit default share an entry.
  /// The reference stays valid until clear() or the Homogenizer is destroyed.
  const HomogenizationResult& homogenize(const WeavePattern& pattern,
                                         int subdivisions = kAutoSubdivisions);
  int cacheHits() const { return cacheHits_; }
  int cacheMisses() const { return cacheMisses_; }
  int cacheSize() const { return static_cast<int>(cache_.size()); }
  void clear();

 private:
  struct Entry {
    std::vector<Matrix2> cellTensors;  ///< Compared on a hit: a hash collision must not alias.
    int cols = 0;
    HomogenizationResult result;
  };
  std::multimap<std::pair<std::uint64_t, int>, Entry> cache_;
  int cacheHits_ = 0;
  int cacheMisses_ = 0;
};

}  // namespace blot::stain
