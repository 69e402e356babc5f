// Helpers shared by the mesh readers: messages, line splitting, number parsing,
// file reading and mesh assembly (declared in mesh_text.h).
#include "mesh_text.h"

#include <blot/stain/io/bounded_read.h>

#include <cerrno>
#include <charconv>
#include <cstdio>
#include <cstring>
#include <utility>

namespace blot::stain::detail {

[[noreturn]] void fail(const std::string& source, const std::string& what) {
  throw MeshError(source + ": " + what);
}

std::string lineText(int line) { return "line " + std::to_string(line); }

/// A token quoted for a message, cut to a readable length.
std::string quoted(string_view token) {
  constexpr size_t maxShown = 32;
  std::string s = "'";
  s.append(token.substr(0, maxShown));
  if (token.size() > maxShown) s += "...";
  return s + "'";
}

std::string vertexName(Eigen::Index v, const ElementOrigins* origins) {
  std::string s = "vertex " + std::to_string(v);
  if (origins && v < static_cast<Eigen::Index>(origins->vertexLines.size()))
    s += " (" + lineText(origins->vertexLines[static_cast<size_t>(v)]) + ")";
  return s;
}

std::string faceName(Eigen::Index f, const ElementOrigins* origins) {
  std::string s = "face " + std::to_string(f);
  if (!origins) return s;
  const auto fs = static_cast<size_t>(f);
  const bool hasPolygon = fs < origins->facePolygons.size() && origins->facePolygons[fs] != f;
  const bool hasLine = fs < origins->faceLines.size();
  if (hasPolygon && hasLine) {
    s += " (file face " + std::to_string(origins->facePolygons[fs]) + ", " +
         lineText(origins->faceLines[fs]) + ")";
  } else if (hasPolygon) {
    s += " (file face " + std::to_string(origins->facePolygons[fs]) + ")";
  } else if (hasLine) {
    s += " (" + lineText(origins->faceLines[fs]) + ")";
  }
  return s;
}

// ---------------------------------------------------------------------------
// Text helpers

bool isBlank(char c) { return c == ' ' || c == '\t' || c == '\r' || c == '\f' || c == '\v'; }

/// Whitespace-separated tokens of `line` up to an optional comment character.
void splitTokens(string_view line, char comment, std::vector<string_view>& tokens) {
  tokens.clear();
  if (comment != '\0') line = line.substr(0, std::min(line.find(comment), line.size()));
  size_t i = 0;
  while (i < line.size()) {
    while (i < line.size() && isBlank(line[i])) ++i;
    const size_t start = i;
    while (i < line.size() && !isBlank(line[i])) ++i;
    if (i > start) tokens.push_back(line.substr(start, i - start));
  }
}

/// Locale-independent full-token parse; accepts a leading '+', "nan" and "inf"
/// (so that non-finite values reach validation and are reported by vertex).
bool parseDouble(string_view token, double& value) {
  if (!token.empty() && token.front() == '+') token.remove_prefix(1);
  if (token.empty()) return false;
  const char* end = token.data() + token.size();
  const auto result = std::from_chars(token.data(), end, value);
  return result.ec == std::errc() && result.ptr == end;
}

bool parseInteger(string_view token, long long& value) {
  if (!token.empty() && token.front() == '+') token.remove_prefix(1);
  if (token.empty()) return false;
  const char* end = token.data() + token.size();
  const auto result = std::from_chars(token.data(), end, value);
  return result.ec == std::errc() && result.ptr == end;
}

std::string readFile(const std::string& path) {
  try {
    return readFileBounded(path, kMeshFileByteLimit, "file");
  } catch (const FileReadError& e) {
    throw MeshError(e.what());
  }
}

/// Builds the mesh arrays from flat buffers; polygons were already fanned.
TriangleMesh assembleMesh(const std::vector<double>& positions, const std::vector<int>& triangles,
                          std::vector<int> labels, const std::vector<double>& uvs) {
  TriangleMesh mesh;
  const auto vertexCount = static_cast<Eigen::Index>(positions.size() / 3);
  const auto faceCount = static_cast<Eigen::Index>(triangles.size() / 3);
  mesh.vertexPositions.resize(vertexCount, 3);
  for (Eigen::Index v = 0; v < vertexCount; ++v)
    for (int k = 0; k < 3; ++k)
      mesh.vertexPositions(v, k) = positions[static_cast<size_t>(3 * v + k)];
  mesh.faces.resize(faceCount, 3);
  for (Eigen::Index f = 0; f < faceCount; ++f)
    for (int k = 0; k < 3; ++k) mesh.faces(f, k) = triangles[static_cast<size_t>(3 * f + k)];
  mesh.faceLabels = std::move(labels);
  if (!uvs.empty()) {
    mesh.vertexUVs.resize(vertexCount, 2);
    for (Eigen::Index v = 0; v < vertexCount; ++v)
      for (int k = 0; k < 2; ++k) mesh.vertexUVs(v, k) = uvs[static_cast<size_t>(2 * v + k)];
  }
  return mesh;
}

/// Appends the fan (c0, ck, ck+1) of one polygon, with its origin and label.
void appendFan(const std::vector<int>& corners, int polygon, int line, bool hasLabel, int label,
               std::vector<int>& triangles, std::vector<int>& labels, ElementOrigins& origins) {
  for (size_t k = 1; k + 1 < corners.size(); ++k) {
    triangles.push_back(corners[0]);
    triangles.push_back(corners[k]);
    triangles.push_back(corners[k + 1]);
    if (hasLabel) labels.push_back(label);
    if (line > 0) origins.faceLines.push_back(line);
    origins.facePolygons.push_back(polygon);
  }
}

}  // namespace blot::stain::detail
