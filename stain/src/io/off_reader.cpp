// The OFF reader.
#include "mesh_text.h"

#include <algorithm>
#include <climits>

namespace blot::stain::detail {

// ---------------------------------------------------------------------------
// OFF

TriangleMesh readOff(const std::string& text, const std::string& path, ElementOrigins& origins) {
  LineReader lines(text);
  std::vector<string_view> tokens;
  string_view line;
  // Next line with data ('#' starts a comment); false at the end of the file.
  const auto nextData = [&]() {
    while (lines.next(line)) {
      splitTokens(line, '#', tokens);
      if (!tokens.empty()) return true;
    }
    return false;
  };
  const auto at = [&]() { return lineText(lines.lineNumber()) + ": "; };

  if (!nextData()) fail(path, "file is empty");
  if (tokens[0] != "OFF") fail(path, at() + "expected the 'OFF' header, got " + quoted(tokens[0]));
  // Counts follow on the header line or on the next data line.
  if (tokens.size() == 1 && !nextData()) fail(path, "file ends before the vertex and face counts");
  const size_t first = tokens[0] == "OFF" ? 1 : 0;
  const int countsLine = lines.lineNumber();
  long long vertexCount = 0, faceCount = 0, edgeCount = 0;
  const size_t countTokens = tokens.size() - first;
  if ((countTokens != 2 && countTokens != 3) || !parseInteger(tokens[first], vertexCount) ||
      !parseInteger(tokens[first + 1], faceCount) ||
      (countTokens == 3 && !parseInteger(tokens[first + 2], edgeCount)) || vertexCount < 0 ||
      faceCount < 0 || vertexCount > INT_MAX || faceCount > INT_MAX) {
    fail(path, at() + "expected '<vertices> <faces> <edges>' counts");
  }
  const std::string countsNote = " (the counts on " + lineText(countsLine) + " declare " +
                                 std::to_string(vertexCount) + " vertices and " +
                                 std::to_string(faceCount) + " faces)";

  const auto cap = [&](long long count) {
    return static_cast<size_t>(
        std::min<long long>(count, static_cast<long long>(text.size() / 2 + 1)));
  };
  std::vector<double> positions;
  positions.reserve(3 * cap(vertexCount));
  origins.vertexLines.reserve(cap(vertexCount));
  for (long long v = 0; v < vertexCount; ++v) {
    if (!nextData()) {
      fail(path, "file ends after " + std::to_string(v) + " of " + std::to_string(vertexCount) +
                     " vertices" + countsNote);
    }
    if (tokens.size() != 3) {
      fail(path, at() + "vertex " + std::to_string(v) + " has " + std::to_string(tokens.size()) +
                     " values, expected 3 (x y z)" + countsNote);
    }
    for (const string_view token : tokens) {
      double value = 0.0;
      if (!parseDouble(token, value))
        fail(path,
             at() + "vertex " + std::to_string(v) + ": expected a number, got " + quoted(token));
      positions.push_back(value);
    }
    origins.vertexLines.push_back(lines.lineNumber());
  }

  std::vector<int> triangles, labels, corners;
  triangles.reserve(3 * cap(faceCount));
  for (long long f = 0; f < faceCount; ++f) {
    if (!nextData()) {
      fail(path, "file ends after " + std::to_string(f) + " of " + std::to_string(faceCount) +
                     " faces" + countsNote);
    }
    const std::string element = "face " + std::to_string(f);
    long long count = 0;
    if (!parseInteger(tokens[0], count))
      fail(path, at() + element + ": expected the corner count, got " + quoted(tokens[0]));
    if (count < 3)
      fail(path,
           at() + element + " has " + std::to_string(count) + " corners, faces need at least 3");
    // Values after the corners are an optional face colour.
    if (static_cast<long long>(tokens.size()) - 1 < count) {
      fail(path, at() + element + " declares " + std::to_string(count) + " corners but lists " +
                     std::to_string(tokens.size() - 1));
    }
    corners.clear();
    for (long long k = 1; k <= count; ++k) {
      const string_view token = tokens[static_cast<size_t>(k)];
      long long index = 0;
      if (!parseInteger(token, index))
        fail(path, at() + element + ": expected a vertex index, got " + quoted(token));
      if (index < 0 || index >= vertexCount) {
        fail(path, element + " (" + lineText(lines.lineNumber()) + "): vertex index " +
                       std::to_string(index) + " out of range [0, " +
                       std::to_string(vertexCount - 1) + "]");
      }
      corners.push_back(static_cast<int>(index));
    }
    // After the corners, OFF allows a colour (3 or 4 numbers), nothing else.
    const size_t extra = tokens.size() - 1 - static_cast<size_t>(count);
    for (size_t k = static_cast<size_t>(count) + 1; k < tokens.size(); ++k) {
      double value = 0;
      if (!parseDouble(tokens[k], value) || extra > 4)
        fail(path, at() + element + ": unexpected " + quoted(tokens[k]) + " after its " + std::to_string(count) +
                       " corners (only a colour of 3 or 4 numbers may follow)");
    }
    appendPolygon(path, corners, positions, static_cast<int>(f), lines.lineNumber(), false, 0, triangles, labels,
                  origins);
  }
  if (nextData()) fail(path, at() + "data after the last face" + countsNote);
  return assembleMesh(positions, triangles, std::move(labels), {});
}

}  // namespace blot::stain::detail
