// Weave patterns: parsing, validation, presets and content hashing.
//
// Design note. A pattern is a periodic tile of square cells with one SPD 2x2
// tensor each (paper sec. 2, Fig. 3c). The cell-letter form builds the tensor
// from pair coefficients as the paper does,
//   S = ½ diag(D_left + D_right, D_top + D_bottom),
// with neighbours taken across the tile's periodic wrap, because the tile is one
// period of an infinite fabric: the cell left of column 0 is the last column.
// Files are validated completely at load time (error tier b): every message
// names the source, the key and the 1-based (row, column) at fault, so a user
// can fix a 30x30 tile without guessing. Rejected alternative: silently
// symmetrising or clamping bad tensors, which would hide a typo in a file and
// make the homogenized result meaningless.
// The content hash is FNV-1a over the exact tensor bits (with -0 folded to +0)
// rather than std::hash of a string, so it is stable across runs, platforms and
// standard libraries, which a cache key written to logs needs.
#include <blot/stain/fabric/weave_pattern.h>
#include <blot/stain/io/bounded_read.h>
#include <blot/stain/io/strict_json.h>

#include <blot/stain/content_hash.h>

#include <nlohmann/json.hpp>

#include <algorithm>
#include <cctype>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <fstream>
#include <limits>
#include <map>
#include <sstream>

namespace blot::stain {

namespace {

/// Relative tolerance for Dxy vs Dyx: files written by other tools print both
/// from the same double, so anything beyond round-off is a real asymmetry.
constexpr double kSymmetryTolerance = 1e-9;

std::string position(int row, int col) {
  return "row " + std::to_string(row + 1) + ", column " + std::to_string(col + 1);
}

/// A number for a message: fixed notation in the usual range, %g beyond it
/// (std::to_string(1e300) is 301 digits).
std::string numberText(double x) {
  if (x == 0 || (std::abs(x) >= 1e-4 && std::abs(x) < 1e15)) return std::to_string(x);
  char text[32];
  std::snprintf(text, sizeof text, "%.6g", x);
  return text;
}

/// Why a symmetric tensor is not acceptable, or empty when it is SPD and finite.
std::string tensorProblem(const Matrix2& tensor) {
  if (!tensor.allFinite()) return "has a non-finite entry";
  const double asym = std::abs(tensor(0, 1) - tensor(1, 0));
  if (asym > kSymmetryTolerance * tensor.cwiseAbs().maxCoeff())
    return "is not symmetric (Dxy = " + numberText(tensor(0, 1)) + ", Dyx = " + numberText(tensor(1, 0)) + ")";
  // Positive definite: Dxx > 0, Dyy > 0 and |Dxy| < sqrt(Dxx) sqrt(Dyy), the
  // determinant's sign without forming Dxx Dyy (diag(1e300, 1e-300) is valid;
  // its product would not overflow, but 1e200 x 1e200 would).
  const double offDiagonal = 0.5 * (tensor(0, 1) + tensor(1, 0));
  const double geometricMean = std::sqrt(std::max(tensor(0, 0), 0.0)) * std::sqrt(std::max(tensor(1, 1), 0.0));
  if (!(tensor(0, 0) > 0.0) || !(tensor(1, 1) > 0.0) || !(std::abs(offDiagonal) < geometricMean)) {
    double det = tensor(0, 0) * tensor(1, 1) - offDiagonal * offDiagonal;
    if (!std::isfinite(det)) det = (geometricMean - std::abs(offDiagonal)) * (geometricMean + std::abs(offDiagonal));
    return "is not positive definite (Dxx = " + numberText(tensor(0, 0)) + ", Dyy = " + numberText(tensor(1, 1)) +
           ", det = " + numberText(det) + ")";
  }
  return {};
}

std::uint64_t hashTensors(int rows, int cols, const std::vector<Matrix2>& tensors) {
  std::uint64_t hash = kContentHashBasis;
  const std::int64_t shape[2] = {rows, cols};
  hashBytes(hash, shape, sizeof(shape));
  for (const Matrix2& tensor : tensors) {
    const double entries[3] = {tensor(0, 0), tensor(0, 1), tensor(1, 1)};
    for (double entry : entries) {
      const double folded = entry == 0.0 ? 0.0 : entry;  // -0 and +0 hash alike.
      hashBytes(hash, &folded, sizeof(folded));
    }
  }
  return hash;
}

bool isCellLetter(char c) { return c == 'W' || c == 'F' || c == 'G'; }

/// Index of the pair {a, b} among the six unordered pairs of W, F, G.
int pairIndex(char a, char b) {
  auto rank = [](char c) { return c == 'G' ? 0 : c == 'F' ? 1 : 2; };
  int i = rank(a), j = rank(b);
  if (i > j) std::swap(i, j);
  // (G,G) (G,F) (G,W) (F,F) (F,W) (W,W)
  static constexpr int table[3][3] = {{0, 1, 2}, {1, 3, 4}, {2, 4, 5}};
  return table[i][j];
}

/// The canonical key of each pair, as docs/patterns.md lists them.
constexpr const char* kPairKeys[6] = {"GG", "FG", "GW", "FF", "FW", "WW"};

PairCoefficients coefficientsFromArray(const double values[6]) {
  PairCoefficients c;
  c.gapGap = values[0];
  c.gapWeft = values[1];
  c.gapWarp = values[2];
  c.weftWeft = values[3];
  c.weftWarp = values[4];
  c.warpWarp = values[5];
  return c;
}

using Json = nlohmann::json;

std::string jsonTypeName(const Json& value) { return value.type_name(); }

/// Rows of cell letters from the "cells" key.
std::vector<std::string> parseCells(const Json& cells, const std::string& source) {
  if (!cells.is_array())
    throw PatternError(source + ": \"cells\": expected an array of strings, got " +
                       jsonTypeName(cells));
  if (cells.empty()) throw PatternError(source + ": \"cells\": expected at least one row");
  std::vector<std::string> rows;
  rows.reserve(cells.size());
  for (size_t r = 0; r < cells.size(); ++r) {
    if (!cells[r].is_string())
      throw PatternError(source + ": \"cells\" row " + std::to_string(r + 1) +
                         ": expected a string of cell letters, got " + jsonTypeName(cells[r]));
    rows.push_back(cells[r].get<std::string>());
  }
  return rows;
}

/// Checks the rows are rectangular and use W, F, G only.
void checkCellLetters(const std::vector<std::string>& cells, const std::string& source) {
  if (cells.empty()) throw PatternError(source + ": \"cells\": expected at least one row");
  if (cells[0].empty())
    throw PatternError(source + ": \"cells\" row 1: expected at least one cell letter");
  for (size_t r = 0; r < cells.size(); ++r) {
    if (cells[r].size() != cells[0].size())
      throw PatternError(source + ": \"cells\" row " + std::to_string(r + 1) + ": has " +
                         std::to_string(cells[r].size()) + " cells, row 1 has " +
                         std::to_string(cells[0].size()) + " (rows must be equally long)");
    for (size_t c = 0; c < cells[r].size(); ++c) {
      if (!isCellLetter(cells[r][c])) {
        const unsigned char ch = static_cast<unsigned char>(cells[r][c]);
        const std::string shown = std::isprint(ch) ? std::string(1, cells[r][c])
                                                   : "\\x" + std::to_string(static_cast<int>(ch));
        throw PatternError(source + ": \"cells\" " +
                           position(static_cast<int>(r), static_cast<int>(c)) +
                           ": unknown cell letter '" + shown + "' (expected W, F or G)");
      }
    }
  }
}

/// Pair coefficients from "pair_coefficients", checking that every pair that
/// occurs between neighbouring cells (with wrap-around) is given.
PairCoefficients parsePairCoefficients(const Json& object, const std::vector<std::string>& cells,
                                       const std::string& source) {
  const std::string key = "\"pair_coefficients\"";
  if (!object.is_object())
    throw PatternError(source + ": " + key + ": expected an object such as {\"GG\": 1, \"FW\": 200}, got " +
                       jsonTypeName(object));
  double values[6];
  std::string givenAs[6];
  for (const auto& [pair, value] : object.items()) {
    if (pair.size() != 2 || !isCellLetter(pair[0]) || !isCellLetter(pair[1]))
      throw PatternError(source + ": " + key + ": unknown pair \"" + pair +
                         "\" (expected two of the letters W, F, G, e.g. \"FW\")");
    const int index = pairIndex(pair[0], pair[1]);
    if (!givenAs[index].empty())
      throw PatternError(source + ": " + key + ": pair \"" + pair + "\" is given twice (also as \"" +
                         givenAs[index] + "\")");
    if (!value.is_number())
      throw PatternError(source + ": " + key + " \"" + pair + "\": expected a number, got " +
                         jsonTypeName(value));
    const double d = value.get<double>();
    if (!std::isfinite(d) || !(d > 0.0))
      throw PatternError(source + ": " + key + " \"" + pair + "\": expected a positive number, got " +
                         std::to_string(d));
    values[index] = d;
    givenAs[index] = pair;
  }
  const int rows = static_cast<int>(cells.size());
  const int cols = static_cast<int>(cells[0].size());
  for (int r = 0; r < rows; ++r) {
    for (int c = 0; c < cols; ++c) {
      const char self = cells[static_cast<size_t>(r)][static_cast<size_t>(c)];
      const char right = cells[static_cast<size_t>(r)][static_cast<size_t>((c + 1) % cols)];
      const char below = cells[static_cast<size_t>((r + 1) % rows)][static_cast<size_t>(c)];
      for (const auto& [other, where] : {std::pair<char, const char*>{right, "right"},
                                         std::pair<char, const char*>{below, "lower"}}) {
        const int index = pairIndex(self, other);
        if (givenAs[index].empty())
          throw PatternError(source + ": " + key + ": missing pair \"" + kPairKeys[index] +
                             "\", needed at \"cells\" " + position(r, c) + " ('" + self +
                             "' next to its " + where + " neighbour '" + other + "')");
      }
    }
  }
  for (int i = 0; i < 6; ++i)
    if (givenAs[i].empty()) values[i] = std::numeric_limits<double>::quiet_NaN();  // unused
  return coefficientsFromArray(values);
}

WeavePattern parseTensors(const Json& tensors, const std::string& source) {
  const std::string key = "\"tensors\"";
  if (!tensors.is_array() || tensors.empty())
    throw PatternError(source + ": " + key +
                       ": expected a non-empty array of rows, each an array of [Dxx, Dxy, Dyx, Dyy]");
  const int rows = static_cast<int>(tensors.size());
  int cols = -1;
  std::vector<Matrix2> cellTensors;
  for (int r = 0; r < rows; ++r) {
    const Json& row = tensors[static_cast<size_t>(r)];
    const std::string rowName = source + ": " + key + " row " + std::to_string(r + 1);
    if (!row.is_array())
      throw PatternError(rowName + ": expected an array of [Dxx, Dxy, Dyx, Dyy], got " + jsonTypeName(row));
    if (row.empty()) throw PatternError(rowName + ": expected at least one cell");
    if (cols < 0) {
      cols = static_cast<int>(row.size());
      cellTensors.reserve(static_cast<size_t>(rows * cols));
    }
    if (static_cast<int>(row.size()) != cols)
      throw PatternError(rowName + ": has " + std::to_string(row.size()) + " cells, row 1 has " +
                         std::to_string(cols) + " (rows must be equally long)");
    for (int c = 0; c < cols; ++c) {
      const Json& cell = row[static_cast<size_t>(c)];
      const std::string cellName = source + ": " + key + " " + position(r, c);
      if (!cell.is_array() || cell.size() != 4)
        throw PatternError(cellName + ": expected [Dxx, Dxy, Dyx, Dyy] (4 numbers), got " +
                           (cell.is_array() ? std::to_string(cell.size()) + " entries" : jsonTypeName(cell)));
      double d[4];
      for (int k = 0; k < 4; ++k) {
        if (!cell[static_cast<size_t>(k)].is_number())
          throw PatternError(cellName + ": entry " + std::to_string(k + 1) + " of [Dxx, Dxy, Dyx, Dyy]" +
                             ": expected a number, got " + jsonTypeName(cell[static_cast<size_t>(k)]));
        d[k] = cell[static_cast<size_t>(k)].get<double>();
      }
      Matrix2 tensor;
      tensor << d[0], d[1], d[2], d[3];
      const std::string problem = tensorProblem(tensor);
      if (!problem.empty()) throw PatternError(cellName + ": tensor " + problem);
      cellTensors.push_back(tensor);
    }
  }
  return WeavePattern(rows, cols, std::move(cellTensors), source);
}

/// Cells of a woven fabric with an n x n interlacing repeat: weft thread i runs
/// along file row 2i, warp thread j along column 2j. The crossing (2i, 2j)
/// shows whichever thread is on top; (2i, 2j+1) is weft between two warps,
/// (2i+1, 2j) warp between two wefts, (2i+1, 2j+1) the gap.
template <typename WarpOnTop>
std::vector<std::string> wovenCells(int repeat, WarpOnTop warpOnTop) {
  std::vector<std::string> cells(static_cast<size_t>(2 * repeat), std::string(static_cast<size_t>(2 * repeat), 'G'));
  for (int i = 0; i < repeat; ++i) {
    for (int j = 0; j < repeat; ++j) {
      auto& weftRow = cells[static_cast<size_t>(2 * i)];
      auto& gapRow = cells[static_cast<size_t>(2 * i + 1)];
      weftRow[static_cast<size_t>(2 * j)] = warpOnTop(i, j) ? 'W' : 'F';
      weftRow[static_cast<size_t>(2 * j + 1)] = 'F';
      gapRow[static_cast<size_t>(2 * j)] = 'W';
      gapRow[static_cast<size_t>(2 * j + 1)] = 'G';
    }
  }
  return cells;
}

std::string normalizedPresetName(const std::string& name) {
  std::string out = name;
  for (char& c : out) c = c == '_' ? '-' : static_cast<char>(std::tolower(static_cast<unsigned char>(c)));
  return out;
}

}  // namespace

WeavePattern::WeavePattern(int rows, int cols, std::vector<Matrix2> cellTensors, std::string sourceName)
    : rows_(rows), cols_(cols), cellTensors_(std::move(cellTensors)), sourceName_(std::move(sourceName)) {
  if (rows < 1 || cols < 1)
    throw PatternError(sourceName_ + ": a pattern needs at least one row and one column, got " +
                       std::to_string(rows) + " x " + std::to_string(cols));
  if (cellTensors_.size() != static_cast<size_t>(rows) * static_cast<size_t>(cols))
    throw PatternError(sourceName_ + ": " + std::to_string(cellTensors_.size()) + " tensors for a " +
                       std::to_string(rows) + " x " + std::to_string(cols) + " tile");
  for (int r = 0; r < rows; ++r) {
    for (int c = 0; c < cols; ++c) {
      Matrix2& tensor = cellTensors_[static_cast<size_t>(r * cols + c)];
      const std::string problem = tensorProblem(tensor);
      if (!problem.empty())
        throw PatternError(sourceName_ + ": cell " + position(r, c) + ": tensor " + problem);
      const double offDiagonal = 0.5 * (tensor(0, 1) + tensor(1, 0));
      tensor(0, 1) = tensor(1, 0) = offDiagonal;
    }
  }
  contentHash_ = hashTensors(rows_, cols_, cellTensors_);
}

WeavePattern WeavePattern::rotated90() const {
  std::vector<Matrix2> tensors;
  tensors.reserve(cellTensors_.size());
  Matrix2 rotation;
  rotation << 0.0, -1.0, 1.0, 0.0;
  // New tile: cols_ rows by rows_ columns; new (r, c) = old (c, cols_ - 1 - r).
  for (int r = 0; r < cols_; ++r)
    for (int c = 0; c < rows_; ++c)
      tensors.push_back(rotation * cellTensor(c, cols_ - 1 - r) * rotation.transpose());
  return WeavePattern(cols_, rows_, std::move(tensors), sourceName_ + " (rotated 90 degrees)");
}

WeavePattern WeavePattern::scaled(double factor) const {
  if (!(factor > 0.0) || !std::isfinite(factor))
    throw PatternError(sourceName_ + ": scale factor must be positive and finite, got " + std::to_string(factor));
  std::vector<Matrix2> tensors = cellTensors_;
  for (Matrix2& tensor : tensors) tensor *= factor;
  return WeavePattern(rows_, cols_, std::move(tensors), sourceName_);
}

double PairCoefficients::between(char a, char b) const {
  switch (pairIndex(a, b)) {
    case 0: return gapGap;
    case 1: return gapWeft;
    case 2: return gapWarp;
    case 3: return weftWeft;
    case 4: return weftWarp;
    default: return warpWarp;
  }
}

PairCoefficients defaultPairCoefficients() { return PairCoefficients{}; }

WeavePattern weavePatternFromCells(const std::vector<std::string>& cells,
                                   const PairCoefficients& coefficients,
                                   const std::string& sourceName) {
  checkCellLetters(cells, sourceName);
  const int rows = static_cast<int>(cells.size());
  const int cols = static_cast<int>(cells[0].size());
  auto letter = [&](int r, int c) {
    return cells[static_cast<size_t>((r + rows) % rows)][static_cast<size_t>((c + cols) % cols)];
  };
  std::vector<Matrix2> tensors;
  tensors.reserve(static_cast<size_t>(rows * cols));
  for (int r = 0; r < rows; ++r) {
    for (int c = 0; c < cols; ++c) {
      const char self = letter(r, c);
      const double left = coefficients.between(self, letter(r, c - 1));
      const double right = coefficients.between(self, letter(r, c + 1));
      const double top = coefficients.between(self, letter(r - 1, c));
      const double bottom = coefficients.between(self, letter(r + 1, c));
      for (double d : {left, right, top, bottom})
        if (!std::isfinite(d) || !(d > 0.0))
          throw PatternError(sourceName + ": \"cells\" " + position(r, c) +
                             ": a pair coefficient with a neighbour is not a positive number");
      Matrix2 tensor = Matrix2::Zero();
      tensor(0, 0) = 0.5 * (left + right);
      tensor(1, 1) = 0.5 * (top + bottom);
      tensors.push_back(tensor);
    }
  }
  return WeavePattern(rows, cols, std::move(tensors), sourceName);
}

WeavePattern parseWeavePattern(const std::string& jsonText, const std::string& sourceName) {
  Json document;
  try {
    document = parseStrictJson(jsonText);
  } catch (const StrictJsonError& e) {
    const std::string what = e.what();
    const std::string syntax = "invalid JSON: ";
    throw PatternError(sourceName + ": " +
                       (what.rfind(syntax, 0) == 0 ? "not valid JSON: " + what.substr(syntax.size()) : what));
  }
  if (!document.is_object())
    throw PatternError(sourceName + ": expected a JSON object with \"tensors\" or \"cells\", got " +
                       jsonTypeName(document));
  for (const auto& [key, value] : document.items()) {
    if (key == "name" || key == "description") {
      if (!value.is_string())
        throw PatternError(sourceName + ": \"" + key + "\": expected a string, got " + jsonTypeName(value));
    } else if (key != "tensors" && key != "cells" && key != "pair_coefficients") {
      throw PatternError(sourceName + ": unknown key \"" + key +
                         "\" (expected \"tensors\", or \"cells\" with \"pair_coefficients\"; "
                         "optional \"name\", \"description\")");
    }
  }
  const bool hasTensors = document.contains("tensors");
  const bool hasCells = document.contains("cells");
  if (hasTensors && hasCells)
    throw PatternError(sourceName + ": give either \"tensors\" or \"cells\", not both");
  if (hasTensors) {
    if (document.contains("pair_coefficients"))
      throw PatternError(sourceName + ": \"pair_coefficients\" is only used with \"cells\", not with \"tensors\"");
    return parseTensors(document["tensors"], sourceName);
  }
  if (!hasCells)
    throw PatternError(sourceName + ": missing key \"tensors\" or \"cells\"");
  const std::vector<std::string> cells = parseCells(document["cells"], sourceName);
  checkCellLetters(cells, sourceName);
  if (!document.contains("pair_coefficients"))
    throw PatternError(sourceName + ": missing key \"pair_coefficients\" (required with \"cells\")");
  const PairCoefficients coefficients =
      parsePairCoefficients(document["pair_coefficients"], cells, sourceName);
  return weavePatternFromCells(cells, coefficients, sourceName);
}

WeavePattern loadWeavePattern(const std::string& path) {
  std::string text;
  try {
    text = readFileBounded(path, kJsonFileByteLimit, "pattern file");
  } catch (const FileReadError& e) {
    throw PatternError(e.what());
  }
  return parseWeavePattern(text, path);
}

std::vector<WeavePreset> weavePresets() {
  const PairCoefficients coefficients = defaultPairCoefficients();
  std::vector<WeavePreset> presets;
  presets.push_back({"plain", "plain weave: each weft passes over one warp, under the next",
                     wovenCells(2, [](int i, int j) { return (i + j) % 2 == 0; }), coefficients});
  presets.push_back({"twill-2-1", "2/1 twill: warp over two wefts, under one, shifted by one per weft",
                     wovenCells(3, [](int i, int j) { return (j - i + 3) % 3 < 2; }), coefficients});
  presets.push_back({"twill-3-1", "3/1 twill: warp over three wefts, under one, shifted by one per weft",
                     wovenCells(4, [](int i, int j) { return (j - i + 4) % 4 < 3; }), coefficients});
  presets.push_back({"satin-5", "5-harness warp-faced satin (move number 2): warp floats over four wefts",
                     wovenCells(5, [](int i, int j) { return j != (2 * i) % 5; }), coefficients});
  presets.push_back({"basket", "2x2 basket weave: pairs of warps over pairs of wefts",
                     wovenCells(4, [](int i, int j) { return (i / 2 + j / 2) % 2 == 0; }), coefficients});
  // 1x1 rib knit: a knit wale (legs W running along the wale, loop hole G,
  // loop head F) beside a purl wale (horizontal F bumps). A stylised layout: the
  // paper gives no knit cell layout, see docs/patterns.md.
  presets.push_back({"rib-knit", "1x1 rib knit: a knit wale (vertical legs) beside a purl wale (horizontal bumps)",
                     {"FFFFFFFF", "WGGWGWWG", "WGGWFFFF", "GWWGGWWG"}, coefficients});
  return presets;
}

WeavePattern presetWeavePattern(const std::string& name) {
  const std::string wanted = normalizedPresetName(name);
  std::string known;
  for (const WeavePreset& preset : weavePresets()) {
    if (preset.name == wanted) return weavePatternFromCells(preset.cells, preset.coefficients, "preset " + preset.name);
    known += (known.empty() ? "" : ", ") + preset.name;
  }
  throw PatternError("unknown pattern preset \"" + name + "\" (known: " + known + ")");
}

}  // namespace blot::stain
