// Helpers shared by the mesh readers: messages, line splitting, number parsing,
// file reading and mesh assembly (declared in mesh_text.h).
#include "mesh_text.h"

#include <blot/stain/io/bounded_read.h>

#include <algorithm>
#include <array>
#include <cerrno>
#include <cmath>
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
    return readFileBounded(path, kMeshFileByteLimit, "file", kMeshStreamByteLimit);
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

namespace {

/// Ear clipping of a simple polygon given in 2D (counter-clockwise): the
/// corners' positions in `order` are cut off one ear at a time. Returns false
/// when no ear is found (the polygon intersects itself).
bool clipEars(std::vector<int> order, const std::vector<std::array<double, 2>>& xy, std::vector<int>& out) {
  const auto cross = [&](int a, int b, int c) {
    return (xy[b][0] - xy[a][0]) * (xy[c][1] - xy[a][1]) - (xy[b][1] - xy[a][1]) * (xy[c][0] - xy[a][0]);
  };
  while (order.size() > 3) {
    const size_t n = order.size();
    bool clipped = false;
    for (size_t i = 0; i < n && !clipped; ++i) {
      const int a = order[(i + n - 1) % n], b = order[i], c = order[(i + 1) % n];
      if (!(cross(a, b, c) > 0)) continue;  // reflex or flat corner: not an ear
      bool empty = true;
      for (size_t k = 0; k < n && empty; ++k) {
        const int q = order[k];
        if (q == a || q == b || q == c) continue;
        if (cross(a, b, q) >= 0 && cross(b, c, q) >= 0 && cross(c, a, q) >= 0) empty = false;
      }
      if (!empty) continue;
      out.insert(out.end(), {a, b, c});
      order.erase(order.begin() + static_cast<std::ptrdiff_t>(i));
      clipped = true;
    }
    if (!clipped) return false;
  }
  if (!(cross(order[0], order[1], order[2]) > 0)) return false;
  out.insert(out.end(), {order[0], order[1], order[2]});
  return true;
}

/// True when two edges of the closed polygon that share no corner cross or touch.
bool selfIntersects(const std::vector<std::array<double, 2>>& xy) {
  const size_t k = xy.size();
  const auto orient = [](const std::array<double, 2>& a, const std::array<double, 2>& b,
                         const std::array<double, 2>& c) {
    const double d = (b[0] - a[0]) * (c[1] - a[1]) - (b[1] - a[1]) * (c[0] - a[0]);
    return (d > 0) - (d < 0);
  };
  const auto within = [](const std::array<double, 2>& a, const std::array<double, 2>& b,
                         const std::array<double, 2>& p) {
    return std::min(a[0], b[0]) <= p[0] && p[0] <= std::max(a[0], b[0]) && std::min(a[1], b[1]) <= p[1] &&
           p[1] <= std::max(a[1], b[1]);
  };
  for (size_t i = 0; i < k; ++i)
    for (size_t j = i + 2; j < k; ++j) {
      if (i == 0 && j == k - 1) continue;  // adjacent through the closing edge
      const auto &a = xy[i], &b = xy[(i + 1) % k], &c = xy[j], &d = xy[(j + 1) % k];
      const int o1 = orient(a, b, c), o2 = orient(a, b, d), o3 = orient(c, d, a), o4 = orient(c, d, b);
      if (o1 != o2 && o3 != o4) return true;
      if ((o1 == 0 && within(a, b, c)) || (o2 == 0 && within(a, b, d)) || (o3 == 0 && within(c, d, a)) ||
          (o4 == 0 && within(c, d, b)))
        return true;
    }
  return false;
}

}  // namespace

void appendPolygon(const std::string& path, const std::vector<int>& corners, const std::vector<double>& positions,
                   int polygon, int line, bool hasLabel, int label, std::vector<int>& triangles,
                   std::vector<int>& labels, ElementOrigins& origins) {
  const size_t k = corners.size();
  const auto emit = [&](int a, int b, int c) {
    triangles.push_back(a);
    triangles.push_back(b);
    triangles.push_back(c);
    if (hasLabel) labels.push_back(label);
    if (line > 0) origins.faceLines.push_back(line);
    origins.facePolygons.push_back(polygon);
  };
  const auto fan = [&] {
    for (size_t j = 1; j + 1 < k; ++j) emit(corners[0], corners[j], corners[j + 1]);
  };
  const std::string where = "face " + std::to_string(polygon) + (line > 0 ? " (" + lineText(line) + ")" : "");
  if (k <= 3) return fan();
  for (const int c : corners)
    if (3 * static_cast<size_t>(c) + 2 >= positions.size())
      fail(path, where + ": a polygon of " + std::to_string(k) +
                     " corners before its vertices (the face element precedes the vertex element) cannot be "
                     "triangulated");
  // The polygon's plane: Newell's normal, then the two axes of its largest component.
  double normal[3] = {0, 0, 0};
  for (size_t j = 0; j < k; ++j) {
    const double* p = &positions[3 * static_cast<size_t>(corners[j])];
    const double* q = &positions[3 * static_cast<size_t>(corners[(j + 1) % k])];
    normal[0] += (p[1] - q[1]) * (p[2] + q[2]);
    normal[1] += (p[2] - q[2]) * (p[0] + q[0]);
    normal[2] += (p[0] - q[0]) * (p[1] + q[1]);
  }
  int drop = 0;
  for (int axis = 1; axis < 3; ++axis)
    if (std::abs(normal[axis]) > std::abs(normal[drop])) drop = axis;
  if (!(std::abs(normal[drop]) > 0) || !std::isfinite(normal[drop])) return fan();  // degenerate: validation names it
  const int u = (drop + 1) % 3, v = (drop + 2) % 3;
  const double sign = normal[drop] > 0 ? 1.0 : -1.0;  // counter-clockwise about the normal
  std::vector<std::array<double, 2>> xy(k);
  for (size_t j = 0; j < k; ++j) {
    const double* p = &positions[3 * static_cast<size_t>(corners[j])];
    xy[j] = {p[u], sign * p[v]};
  }
  // A convex polygon keeps the fan (c0, cj, cj+1) it always had.
  bool convex = true;
  for (size_t j = 0; j < k && convex; ++j) {
    const auto& a = xy[j];
    const auto& b = xy[(j + 1) % k];
    const auto& c = xy[(j + 2) % k];
    convex = (b[0] - a[0]) * (c[1] - a[1]) - (b[1] - a[1]) * (c[0] - a[0]) >= 0;
  }
  if (convex) return fan();
  if (k > kMaxClippedPolygonCorners)
    fail(path, where + ": a non-convex polygon of " + std::to_string(k) + " corners; at most " +
                   std::to_string(kMaxClippedPolygonCorners) + " are triangulated");
  std::vector<int> order(k), local;
  for (size_t j = 0; j < k; ++j) order[j] = static_cast<int>(j);
  if (selfIntersects(xy) || !clipEars(order, xy, local))
    fail(path, where + ": the polygon of " + std::to_string(k) +
                   " corners intersects itself (or folds onto itself); it cannot be triangulated");
  for (size_t t = 0; t < local.size(); t += 3)
    emit(corners[static_cast<size_t>(local[t])], corners[static_cast<size_t>(local[t + 1])],
         corners[static_cast<size_t>(local[t + 2])]);
}

}  // namespace blot::stain::detail
