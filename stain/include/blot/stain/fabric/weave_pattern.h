#pragma once
/// Weave patterns: one periodic tile of square cells, each with a 2x2 diffusion
/// tensor (paper sec. 2), read from JSON files (docs/patterns.md) or built from
/// named presets.
///
/// Coordinates: x runs along the weft (columns, left to right), y along the warp
/// (rows, upwards); the first row of a file is the TOP row of the tile. Cell
/// (row, col) below uses file order: row 0 is the top row. Every tensor is
/// expressed in (x, y) = (weft, warp) and is symmetric positive definite, in the
/// diffusion units of the scene (m²/s in the engine).
#include <blot/stain/types.h>

#include <cstdint>
#include <stdexcept>
#include <string>
#include <vector>

namespace blot::stain {

/// Input-data error (tier b) in a pattern file or pattern definition. The
/// message starts with the source (file path or description) and names the key
/// and, for cell errors, the position, e.g.
///   "cloth.json: \"cells\" row 2, column 5: unknown cell letter 'X' (expected W, F or G)".
class PatternError : public std::runtime_error {
 public:
  using std::runtime_error::runtime_error;
};

/// A periodic tile of rows x cols square cells with one SPD 2x2 tensor per cell.
/// Immutable once built; the constructor validates every tensor.
class WeavePattern {
 public:
  /// `cellTensors` row-major (rows * cols entries, row 0 = top row), each
  /// symmetric positive definite (relative asymmetry <= 1e-9). Throws
  /// PatternError naming `sourceName` and the cell (row, column) otherwise.
  WeavePattern(int rows, int cols, std::vector<Matrix2> cellTensors,
               std::string sourceName = "pattern");

  int rows() const { return rows_; }
  int cols() const { return cols_; }
  /// Tensor of cell (row, col), row 0 = top; (x, y) = (weft, warp) components.
  const Matrix2& cellTensor(int row, int col) const {
    return cellTensors_[static_cast<size_t>(row * cols_ + col)];
  }
  /// All rows * cols tensors, row-major, row 0 = top.
  const std::vector<Matrix2>& cellTensors() const { return cellTensors_; }
  /// Where the pattern came from (file path, preset name), for messages.
  const std::string& sourceName() const { return sourceName_; }
  /// 64-bit FNV-1a hash of (rows, cols, tensor bits): equal content gives equal
  /// hashes whatever the source, so homogenization results can be cached by it.
  std::uint64_t contentHash() const { return contentHash_; }
  /// The same tile rotated by 90° counter-clockwise (x -> y): new cell (r, c)
  /// is old cell (c, cols - 1 - r), tensors conjugated by the rotation. Its
  /// effective tensor is the old one with x and y exchanged (off-diagonal negated).
  WeavePattern rotated90() const;
  /// Each tensor multiplied by `factor` > 0 (e.g. a scene's diffusion scale).
  WeavePattern scaled(double factor) const;

 private:
  int rows_ = 0;
  int cols_ = 0;
  std::vector<Matrix2> cellTensors_;
  std::string sourceName_;
  std::uint64_t contentHash_ = 0;
};

/// Pair diffusion coefficients D between neighbouring cell types (paper sec. 2:
/// W = warp, F = weft, G = gap), each > 0, in the pattern's diffusion units.
struct PairCoefficients {
  double gapGap = 1.0;     ///< "GG"
  double weftWeft = 100.0; ///< "FF"
  double warpWarp = 500.0; ///< "WW"
  double gapWeft = 10.0;   ///< "FG" (or "GF")
  double gapWarp = 50.0;   ///< "GW" (or "WG")
  double weftWarp = 200.0; ///< "FW" (or "WF")
  /// Coefficient between cell letters a and b (each 'W', 'F' or 'G'; order free).
  double between(char a, char b) const;
};

/// The defaults of PairCoefficients are the paper's Fig. 4 knit values
/// (GG 1, FF 100, WW 500, FG 10, GW 50, FW 200); every preset uses them.
PairCoefficients defaultPairCoefficients();

/// Per-cell tensors from cell letters: cell (r, c) gets the paper's
/// S = ½ diag(D_left + D_right, D_top + D_bottom), D_left the pair coefficient
/// between the cell and its left neighbour, wrapping around the tile. `cells`
/// holds one string per row (top row first), all the same length, letters W, F,
/// G only. Throws PatternError (ragged rows, unknown letters) naming the row and
/// column.
WeavePattern weavePatternFromCells(const std::vector<std::string>& cells,
                                   const PairCoefficients& coefficients,
                                   const std::string& sourceName = "cells");

/// Parses a pattern document (either form of docs/patterns.md). `sourceName`
/// prefixes every error message. Throws PatternError on any malformed input:
/// invalid JSON, unknown or missing keys, wrong types, ragged rows, unknown
/// letters, missing or duplicated pair coefficients, non-symmetric or
/// non-positive-definite tensors.
WeavePattern parseWeavePattern(const std::string& jsonText, const std::string& sourceName);

/// Reads and parses a pattern file; errors name the path.
WeavePattern loadWeavePattern(const std::string& path);

/// A named preset: cell letters (top row first) and its default coefficients.
struct WeavePreset {
  std::string name;                ///< e.g. "twill-2-1".
  std::string description;         ///< One line for docs and `--help`.
  std::vector<std::string> cells;  ///< One string per row, top row first.
  PairCoefficients coefficients;   ///< defaultPairCoefficients().
};

/// All presets, in a fixed order: plain, twill-2-1, twill-3-1, satin-5, basket,
/// rib-knit.
std::vector<WeavePreset> weavePresets();

/// The preset called `name` ('_' and '-' are interchangeable, case-insensitive),
/// as a pattern. Throws PatternError listing the known names otherwise.
WeavePattern presetWeavePattern(const std::string& name);

}  // namespace blot::stain
