// Private to stain/src/io: the helpers the mesh readers, the validation and
// mesh_io.cpp share, and the entry points of the per-format readers.
#pragma once

#include <blot/stain/io/mesh_io.h>

#include <algorithm>
#include <string>
#include <string_view>
#include <vector>

namespace blot::stain::detail {

using std::string_view;

[[noreturn]] void fail(const std::string& source, const std::string& what);

std::string lineText(int line);

/// A token quoted for a message, cut to a readable length.
std::string quoted(string_view token);

/// Where each element of a loaded mesh came from, for messages. Empty vectors
/// mean "unknown" (binary data, meshes built in code).
struct ElementOrigins {
  std::vector<int> vertexLines;   ///< #V, 1-based line numbers.
  std::vector<int> faceLines;     ///< #F, line of the polygon each triangle was cut from.
  std::vector<int> facePolygons;  ///< #F, index of that polygon among the file's faces.
};

std::string vertexName(Eigen::Index v, const ElementOrigins* origins);
std::string faceName(Eigen::Index f, const ElementOrigins* origins);

/// Splits a buffer into lines ending in "\n", "\r\n" or "\r" (the same rule
/// tinyobjloader uses, so line numbers agree). A final newline does not start
/// an extra empty line.
class LineReader {
 public:
  explicit LineReader(string_view text) : text_(text) {}

  bool next(string_view& line) {
    if (pos_ >= text_.size()) return false;
    const size_t end = std::min(text_.find_first_of("\r\n", pos_), text_.size());
    line = text_.substr(pos_, end - pos_);
    pos_ = end;
    if (pos_ < text_.size()) {
      pos_ += (text_[pos_] == '\r' && pos_ + 1 < text_.size() && text_[pos_ + 1] == '\n') ? 2 : 1;
    }
    ++lineNumber_;
    return true;
  }
  /// 1-based number of the line last returned by next().
  int lineNumber() const { return lineNumber_; }
  /// Byte offset just past the last line returned (and its newline).
  size_t offset() const { return pos_; }

 private:
  string_view text_;
  size_t pos_ = 0;
  int lineNumber_ = 0;
};

bool isBlank(char c);

/// Whitespace-separated tokens of `line` up to an optional comment character.
void splitTokens(string_view line, char comment, std::vector<string_view>& tokens);

/// Locale-independent full-token parse; accepts a leading '+', "nan" and "inf"
/// (so that non-finite values reach validation and are reported by vertex).
bool parseDouble(string_view token, double& value);
bool parseInteger(string_view token, long long& value);

std::string readFile(const std::string& path);

/// Builds the mesh arrays from flat buffers; polygons were already fanned.
TriangleMesh assembleMesh(const std::vector<double>& positions, const std::vector<int>& triangles,
                          std::vector<int> labels, const std::vector<double>& uvs);

/// Non-convex polygons with more corners are refused (ear clipping is O(k^3)).
inline constexpr size_t kMaxClippedPolygonCorners = 1000;

/// Appends the triangles of one polygon (corners index `positions`, xyz
/// triples), with its origin and label: a convex polygon as the fan (c0, ck,
/// ck+1), a non-convex one by ear clipping in its plane (Newell normal), so a
/// concave quad keeps its area. A self-intersecting polygon, or one whose
/// vertices are not read yet, is a MeshError naming the face and line.
void appendPolygon(const std::string& path, const std::vector<int>& corners, const std::vector<double>& positions,
                   int polygon, int line, bool hasLabel, int label, std::vector<int>& triangles,
                   std::vector<int>& labels, ElementOrigins& origins);

// The readers (obj_reader.cpp, ply_reader.cpp, off_reader.cpp) and the checks
// every loaded mesh goes through (mesh_validation.cpp).
TriangleMesh readObj(const std::string& text, const std::string& path, ElementOrigins& origins);
TriangleMesh readPly(const std::string& text, const std::string& path, ElementOrigins& origins);
TriangleMesh readOff(const std::string& text, const std::string& path, ElementOrigins& origins);
void validateWithOrigins(const TriangleMesh& mesh, const std::string& source,
                         const ElementOrigins* origins);

}  // namespace blot::stain::detail
