// Weave patterns: both JSON forms, the pair-coefficient tensor rule with
// wrap-around, presets and their asset files, content hashing, rotation, and
// every kind of bad file rejected with a message naming key and position.
#include <blot/stain/fabric/weave_pattern.h>

#include <gtest/gtest.h>

#include <string>
#include <vector>

namespace blot::stain {
namespace {

// Expects parseWeavePattern(text) to throw PatternError whose message contains
// every fragment (the key, the position, what was expected).
void expectRejected(const std::string& text, const std::vector<std::string>& fragments) {
  SCOPED_TRACE(text);
  try {
    parseWeavePattern(text, "bad.json");
    ADD_FAILURE() << "accepted a bad pattern";
  } catch (const PatternError& e) {
    const std::string message = e.what();
    EXPECT_EQ(message.rfind("bad.json: ", 0), 0u) << message;
    for (const std::string& fragment : fragments)
      EXPECT_NE(message.find(fragment), std::string::npos) << "missing '" << fragment << "' in: " << message;
  }
}

TEST(WeavePattern, TensorFormKeepsFileOrderTopRowFirst) {
  const WeavePattern p = parseWeavePattern(
      R"({"tensors": [[[1, 0, 0, 2], [3, 0.5, 0.5, 4]],
                      [[5, 0, 0, 6], [7, -1, -1, 8]]]})",
      "two.json");
  ASSERT_EQ(p.rows(), 2);
  ASSERT_EQ(p.cols(), 2);
  EXPECT_EQ(p.cellTensor(0, 0)(1, 1), 2.0);  // top-left
  EXPECT_EQ(p.cellTensor(0, 1)(0, 1), 0.5);  // top-right, Dxy
  EXPECT_EQ(p.cellTensor(1, 0)(0, 0), 5.0);  // bottom-left
  EXPECT_EQ(p.cellTensor(1, 1)(1, 0), -1.0);
  EXPECT_EQ(p.sourceName(), "two.json");
}

TEST(WeavePattern, CellFormAppliesPaperRuleWithWrapAround) {
  // One row "WFG": left/right neighbours wrap (W's left is G); top and bottom
  // wrap onto the row itself, so D_top = D_bottom = the cell's own pair.
  const WeavePattern p = parseWeavePattern(
      R"({"cells": ["WFG"], "pair_coefficients":
          {"GG": 1, "FF": 100, "WW": 500, "FG": 10, "GW": 50, "FW": 200}})",
      "row.json");
  ASSERT_EQ(p.rows(), 1);
  ASSERT_EQ(p.cols(), 3);
  EXPECT_DOUBLE_EQ(p.cellTensor(0, 0)(0, 0), 0.5 * (50 + 200));  // W: left G, right F
  EXPECT_DOUBLE_EQ(p.cellTensor(0, 0)(1, 1), 500);               // W over W
  EXPECT_DOUBLE_EQ(p.cellTensor(0, 1)(0, 0), 0.5 * (200 + 10));  // F: left W, right G
  EXPECT_DOUBLE_EQ(p.cellTensor(0, 1)(1, 1), 100);
  EXPECT_DOUBLE_EQ(p.cellTensor(0, 2)(0, 0), 0.5 * (10 + 50));   // G: left F, right W
  EXPECT_DOUBLE_EQ(p.cellTensor(0, 2)(1, 1), 1);
  for (const Matrix2& s : p.cellTensors()) EXPECT_EQ(s(0, 1), 0.0);
}

TEST(WeavePattern, CellFormVerticalNeighboursWrapAndTopRowIsFirst) {
  // Column "W" over "G" over "F" (top to bottom): W's top neighbour is F (wrap).
  const WeavePattern p = parseWeavePattern(
      R"({"cells": ["W", "G", "F"], "pair_coefficients":
          {"GG": 1, "FF": 100, "WW": 500, "FG": 10, "GW": 50, "FW": 200}})",
      "column.json");
  EXPECT_DOUBLE_EQ(p.cellTensor(0, 0)(1, 1), 0.5 * (200 + 50));  // W: top F, bottom G
  EXPECT_DOUBLE_EQ(p.cellTensor(0, 0)(0, 0), 500);
  EXPECT_DOUBLE_EQ(p.cellTensor(1, 0)(1, 1), 0.5 * (50 + 10));   // G: top W, bottom F
  EXPECT_DOUBLE_EQ(p.cellTensor(2, 0)(1, 1), 0.5 * (10 + 200));  // F: top G, bottom W
}

TEST(WeavePattern, PairKeysInEitherOrderGiveTheSamePattern) {
  const WeavePattern a = parseWeavePattern(
      R"({"cells": ["WFG", "GWF"], "pair_coefficients":
          {"GG": 1, "FF": 100, "WW": 500, "FG": 10, "GW": 50, "FW": 200}})", "a");
  const WeavePattern b = parseWeavePattern(
      R"({"cells": ["WFG", "GWF"], "pair_coefficients":
          {"GG": 1, "FF": 100, "WW": 500, "GF": 10, "WG": 50, "WF": 200}})", "b");
  EXPECT_EQ(a.cellTensors(), b.cellTensors());
  EXPECT_EQ(a.contentHash(), b.contentHash());
}

TEST(WeavePattern, OnlyPairsThatOccurAreRequired) {
  const WeavePattern p =
      parseWeavePattern(R"({"cells": ["WF", "FW"], "pair_coefficients": {"FW": 3}, "name": "checker"})", "x");
  for (const Matrix2& s : p.cellTensors()) EXPECT_EQ(s, 3.0 * Matrix2::Identity());
}

TEST(WeavePattern, PresetsAreValidAndMatchTheirAssetFiles) {
  const std::vector<std::string> expected = {"plain", "twill-2-1", "twill-3-1", "satin-5", "basket", "rib-knit"};
  const std::vector<WeavePreset> presets = weavePresets();
  ASSERT_EQ(presets.size(), expected.size());
  for (size_t i = 0; i < presets.size(); ++i) {
    SCOPED_TRACE(presets[i].name);
    EXPECT_EQ(presets[i].name, expected[i]);
    const WeavePattern p = presetWeavePattern(presets[i].name);
    EXPECT_EQ(p.rows(), static_cast<int>(presets[i].cells.size()));
    // The asset file (underscores) holds the same cells and coefficients.
    std::string file = presets[i].name;
    for (char& c : file) c = c == '-' ? '_' : c;
    const WeavePattern asset = loadWeavePattern(std::string(BLOT_ASSETS_DIR) + "/patterns/" + file + ".json");
    EXPECT_EQ(asset.cellTensors(), p.cellTensors());
    EXPECT_EQ(asset.contentHash(), p.contentHash());
  }
  EXPECT_EQ(presetWeavePattern("Twill_2_1").contentHash(), presetWeavePattern("twill-2-1").contentHash());
  try {
    presetWeavePattern("velvet");
    ADD_FAILURE() << "unknown preset accepted";
  } catch (const PatternError& e) {
    EXPECT_NE(std::string(e.what()).find("rib-knit"), std::string::npos) << e.what();
  }
}

TEST(WeavePattern, WovenPresetsHaveTheirInterlacing) {
  // Plain weave: crossings alternate W/F along a weft row (file row 0) and
  // between consecutive wefts; gap cells sit between threads.
  const std::vector<WeavePreset> presets = weavePresets();
  EXPECT_EQ(presets[0].cells, (std::vector<std::string>{"WFFF", "WGWG", "FFWF", "WGWG"}));
  // 5-harness satin: exactly one weft-over crossing per weft row and per warp column.
  const std::vector<std::string>& satin = presets[3].cells;
  ASSERT_EQ(satin.size(), 10u);
  for (int i = 0; i < 5; ++i) {
    int weftUpInRow = 0, weftUpInColumn = 0;
    for (int j = 0; j < 5; ++j) {
      weftUpInRow += satin[2 * i][2 * j] == 'F';
      weftUpInColumn += satin[2 * j][2 * i] == 'F';
    }
    EXPECT_EQ(weftUpInRow, 1);
    EXPECT_EQ(weftUpInColumn, 1);
  }
}

TEST(WeavePattern, HashDependsOnContentOnly) {
  const WeavePattern plain = presetWeavePattern("plain");
  const WeavePattern again(plain.rows(), plain.cols(), plain.cellTensors(), "another name");
  EXPECT_EQ(plain.contentHash(), again.contentHash());
  EXPECT_NE(plain.contentHash(), presetWeavePattern("basket").contentHash());
  EXPECT_NE(plain.contentHash(), plain.scaled(2.0).contentHash());
  // Same numbers, different shape: 1x2 vs 2x1.
  const std::vector<Matrix2> two = {Matrix2::Identity(), 2.0 * Matrix2::Identity()};
  EXPECT_NE(WeavePattern(1, 2, two).contentHash(), WeavePattern(2, 1, two).contentHash());
  // A tiny change of one entry changes the hash.
  std::vector<Matrix2> nudged = plain.cellTensors();
  nudged[5](0, 0) = std::nextafter(nudged[5](0, 0), 1e9);
  EXPECT_NE(WeavePattern(plain.rows(), plain.cols(), nudged).contentHash(), plain.contentHash());
}

TEST(WeavePattern, Rotated90MapsCellsAndTensors) {
  // 2 rows x 3 columns, cell (r, c) = diag(10r + c + 1, 1) with an off-diagonal.
  std::vector<Matrix2> tensors;
  for (int r = 0; r < 2; ++r)
    for (int c = 0; c < 3; ++c) {
      Matrix2 s;
      s << 10 * r + c + 1, 0.25, 0.25, 1;
      tensors.push_back(s);
    }
  const WeavePattern p(2, 3, tensors);
  const WeavePattern q = p.rotated90();
  ASSERT_EQ(q.rows(), 3);
  ASSERT_EQ(q.cols(), 2);
  for (int r = 0; r < 3; ++r)
    for (int c = 0; c < 2; ++c) {
      const Matrix2& old = p.cellTensor(c, 2 - r);
      const Matrix2& now = q.cellTensor(r, c);
      EXPECT_EQ(now(0, 0), old(1, 1));
      EXPECT_EQ(now(1, 1), old(0, 0));
      EXPECT_EQ(now(0, 1), -old(0, 1));
    }
  // Old top-left cell -> new last row, first column (file order).
  EXPECT_EQ(q.cellTensor(2, 0)(1, 1), p.cellTensor(0, 0)(0, 0));
  EXPECT_EQ(q.rotated90().rotated90().rotated90().rotated90().contentHash(), q.contentHash());
}

TEST(WeavePattern, RejectsRaggedRows) {
  expectRejected(R"({"cells": ["WFG", "WF"], "pair_coefficients": {"FW": 1}})",
                 {"\"cells\" row 2", "has 2 cells, row 1 has 3"});
  expectRejected(R"({"tensors": [[[1,0,0,1], [1,0,0,1]], [[1,0,0,1]]]})",
                 {"\"tensors\" row 2", "has 1 cells, row 1 has 2"});
}

TEST(WeavePattern, RejectsUnknownLetters) {
  expectRejected(R"({"cells": ["WFG", "WXG"], "pair_coefficients": {"FW": 1}})",
                 {"\"cells\" row 2, column 2", "unknown cell letter 'X'"});
  expectRejected(R"({"cells": ["wf"], "pair_coefficients": {"FW": 1}})",
                 {"\"cells\" row 1, column 1", "'w'"});
  expectRejected(R"({"cells": ["WF"], "pair_coefficients": {"FX": 1}})",
                 {"\"pair_coefficients\"", "unknown pair \"FX\""});
}

TEST(WeavePattern, RejectsMissingOrDuplicatedPairs) {
  expectRejected(R"({"cells": ["WF", "GG"], "pair_coefficients": {"FW": 1, "WW": 2, "GW": 3}})",
                 {"\"pair_coefficients\"", "missing pair \"FG\"", "row 1, column 2", "lower neighbour 'G'"});
  expectRejected(R"({"cells": ["WF"]})", {"missing key \"pair_coefficients\""});
  expectRejected(R"({"cells": ["WF"], "pair_coefficients": {"FW": 1, "WF": 1, "WW": 1, "FF": 1}})",
                 {"\"pair_coefficients\"", "given twice"});
  expectRejected(R"({"cells": ["WF"], "pair_coefficients": {"FW": 0, "WW": 1, "FF": 1}})",
                 {"\"pair_coefficients\" \"FW\"", "positive"});
}

TEST(WeavePattern, RejectsNonSymmetricAndNonPositiveDefiniteTensors) {
  expectRejected(R"({"tensors": [[[1,0,0,1], [2, 0.5, 0.4, 2]]]})",
                 {"\"tensors\" row 1, column 2", "not symmetric"});
  expectRejected(R"({"tensors": [[[1,0,0,1]], [[1, 2, 2, 1]]]})",
                 {"\"tensors\" row 2, column 1", "not positive definite"});
  expectRejected(R"({"tensors": [[[-1,0,0,1]]]})", {"\"tensors\" row 1, column 1", "not positive definite"});
  expectRejected(R"({"tensors": [[[0,0,0,0]]]})", {"row 1, column 1", "not positive definite"});
  // In-memory patterns are checked the same way.
  EXPECT_THROW(WeavePattern(1, 1, {Matrix2::Zero()}), PatternError);
}

TEST(WeavePattern, RejectsWrongTypes) {
  expectRejected(R"([1, 2])", {"expected a JSON object"});
  expectRejected(R"({"tensors": [[[1, 0, 0, "1"]]]})",
                 {"\"tensors\" row 1, column 1", "entry 4", "expected a number, got string"});
  expectRejected(R"({"tensors": [[[1, 0, 0]]]})", {"\"tensors\" row 1, column 1", "4 numbers", "3 entries"});
  expectRejected(R"({"tensors": [[1, 0, 0, 1]]})", {"\"tensors\" row 1, column 1", "got number"});
  expectRejected(R"({"tensors": [{"a": 1}]})", {"\"tensors\" row 1", "got object"});
  expectRejected(R"({"tensors": {}})", {"\"tensors\"", "non-empty array"});
  expectRejected(R"({"cells": "WFG", "pair_coefficients": {"FW": 1}})", {"\"cells\"", "got string"});
  expectRejected(R"({"cells": ["WF", 3], "pair_coefficients": {"FW": 1}})", {"\"cells\" row 2", "got number"});
  expectRejected(R"({"cells": ["WF"], "pair_coefficients": [1, 2]})", {"\"pair_coefficients\"", "got array"});
  expectRejected(R"({"cells": ["WF"], "pair_coefficients": {"FW": "1", "WW": 1, "FF": 1}})",
                 {"\"pair_coefficients\" \"FW\"", "got string"});
  expectRejected(R"({"cells": ["WF"], "pair_coefficients": {"FW": true, "WW": 1, "FF": 1}})",
                 {"\"pair_coefficients\" \"FW\"", "got boolean"});
  expectRejected(R"({"name": 3, "tensors": [[[1,0,0,1]]]})", {"\"name\"", "expected a string"});
}

TEST(WeavePattern, RejectsUnknownKeysMixedFormsAndBadJson) {
  expectRejected(R"({"tensor": [[[1,0,0,1]]]})", {"unknown key \"tensor\""});
  expectRejected(R"({"tensors": [[[1,0,0,1]]], "cells": ["W"]})", {"either \"tensors\" or \"cells\""});
  expectRejected(R"({"tensors": [[[1,0,0,1]]], "pair_coefficients": {"WW": 1}})",
                 {"\"pair_coefficients\" is only used with \"cells\""});
  expectRejected(R"({})", {"missing key \"tensors\" or \"cells\""});
  expectRejected(R"({"tensors": [[[1,0,0,1]]]  )", {"not valid JSON", "line 1"});
  EXPECT_THROW(loadWeavePattern("/nonexistent/pattern.json"), PatternError);
}

}  // namespace
}  // namespace blot::stain
