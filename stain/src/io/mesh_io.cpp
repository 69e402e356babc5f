// Reading and writing triangle meshes: OBJ, PLY (ASCII, binary little-endian), OFF.
//
// Design note: docs/design-notes.md, "stain/src/io/mesh_io.cpp".
#include <blot/stain/io/mesh_io.h>

#include <blot/stain/io/atomic_file.h>
#include <blot/stain/geometry/surface_topology.h>
#include <tiny_obj_loader.h>

#include <algorithm>
#include <cctype>
#include <cerrno>
#include <charconv>
#include <climits>
#include <cmath>
#include <cstdint>
#include <cstdio>
#include <cstring>
#include <map>
#include <sstream>
#include <string_view>
#include <utility>
#include <vector>

namespace blot::stain {
namespace {

using std::string_view;

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

/// Where each element of a loaded mesh came from, for messages. Empty vectors
/// mean "unknown" (binary data, meshes built in code).
struct ElementOrigins {
  std::vector<int> vertexLines;   ///< #V, 1-based line numbers.
  std::vector<int> faceLines;     ///< #F, line of the polygon each triangle was cut from.
  std::vector<int> facePolygons;  ///< #F, index of that polygon among the file's faces.
};

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
  errno = 0;
  std::FILE* file = std::fopen(path.c_str(), "rb");
  if (!file) fail(path, std::string("cannot open file: ") + std::strerror(errno));
  std::string text;
  char buffer[1 << 16];
  size_t n = 0;
  while ((n = std::fread(buffer, 1, sizeof buffer, file)) > 0) text.append(buffer, n);
  const bool readError = std::ferror(file) != 0;
  const int readErrno = errno;
  std::fclose(file);
  if (readError) fail(path, std::string("cannot read file: ") + std::strerror(readErrno));
  return text;
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

// ---------------------------------------------------------------------------
// Validation

void validateWithOrigins(const TriangleMesh& mesh, const std::string& source,
                         const ElementOrigins* origins) {
  const Eigen::Index vertexCount = mesh.vertexPositions.rows();
  const Eigen::Index faceCount = mesh.faces.rows();
  if (vertexCount == 0 || faceCount == 0) {
    fail(source, "mesh is empty (" + std::to_string(vertexCount) + " vertices, " +
                     std::to_string(faceCount) + " faces)");
  }
  if (vertexCount > INT_MAX) fail(source, "too many vertices for 32-bit indices");
  if (!mesh.faceLabels.empty() && static_cast<Eigen::Index>(mesh.faceLabels.size()) != faceCount) {
    fail(source, std::to_string(mesh.faceLabels.size()) + " face labels for " +
                     std::to_string(faceCount) + " faces");
  }
  if (mesh.vertexUVs.rows() != 0 && mesh.vertexUVs.rows() != vertexCount) {
    fail(source, std::to_string(mesh.vertexUVs.rows()) + " texture coordinates for " +
                     std::to_string(vertexCount) + " vertices");
  }

  for (Eigen::Index v = 0; v < vertexCount; ++v) {
    if (!mesh.vertexPositions.row(v).allFinite()) {
      std::ostringstream s;
      s << vertexName(v, origins) << " has a non-finite coordinate (" << mesh.vertexPositions(v, 0)
        << ", " << mesh.vertexPositions(v, 1) << ", " << mesh.vertexPositions(v, 2) << ")";
      fail(source, s.str());
    }
    if (mesh.vertexUVs.rows() != 0 && !mesh.vertexUVs.row(v).allFinite())
      fail(source, vertexName(v, origins) + " has a non-finite texture coordinate");
  }

  for (Eigen::Index f = 0; f < faceCount; ++f) {
    for (int k = 0; k < 3; ++k) {
      const int index = mesh.faces(f, k);
      if (index < 0 || index >= vertexCount) {
        fail(source, faceName(f, origins) + ": vertex index " + std::to_string(index) +
                         " out of range [0, " + std::to_string(vertexCount - 1) + "]");
      }
    }
  }

  for (Eigen::Index f = 0; f < faceCount; ++f) {
    const int a = mesh.faces(f, 0), b = mesh.faces(f, 1), c = mesh.faces(f, 2);
    if (a == b || b == c || a == c) {
      fail(source, faceName(f, origins) + " repeats a vertex (" + std::to_string(a) + ", " +
                       std::to_string(b) + ", " + std::to_string(c) + ")");
    }
  }

  const Vector3 extent =
      mesh.vertexPositions.colwise().maxCoeff() - mesh.vertexPositions.colwise().minCoeff();
  const double minArea = 1e-14 * extent.squaredNorm();
  for (Eigen::Index f = 0; f < faceCount; ++f) {
    const Vector3 p0 = mesh.vertexPositions.row(mesh.faces(f, 0));
    const Vector3 p1 = mesh.vertexPositions.row(mesh.faces(f, 1));
    const Vector3 p2 = mesh.vertexPositions.row(mesh.faces(f, 2));
    const double area = 0.5 * (p1 - p0).cross(p2 - p0).norm();
    if (area <= minArea) {
      std::ostringstream s;
      s << faceName(f, origins) << " has zero area (" << area
        << " <= 1e-14 * bounding-box diagonal^2 = " << minArea << ")";
      fail(source, s.str());
    }
  }

  // Manifoldness, orientation, unreferenced vertices.
  const SurfaceTopology topology(mesh.faces, static_cast<int>(vertexCount), source);
  (void)topology;
}

// ---------------------------------------------------------------------------
// OBJ

/// What our own line scan of an OBJ file records (see the design note).
struct ObjScan {
  std::vector<double> positions;  ///< 3 per `v` line.
  std::vector<int> positionLines;
  std::vector<double> texcoords;  ///< 2 per `vt` line (v = 0 when absent).
  std::vector<int> polygonLines;
  std::vector<int> polygonCorners;
  std::vector<int> polygonLabels;
  bool hasLabels = false;
};

/// A positive index beyond the elements defined so far: OBJ allows forward
/// references, so it is checked once the whole file has been read.
struct PendingIndex {
  int polygon;
  int line;
  long long index;
  bool texcoord;
};

ObjScan scanObj(string_view text, const std::string& path) {
  ObjScan scan;
  std::vector<string_view> tokens, parts;
  std::vector<PendingIndex> pending;
  std::map<std::pair<std::string, std::string>, int> labelIds;
  std::string group, material;
  bool groupOrMaterialSeen = false;
  int currentLabel = -1;  // label of (group, material); -1 after either changes
  LineReader lines(text);
  string_view line;
  while (lines.next(line)) {
    const int lineNumber = lines.lineNumber();
    const auto where = [&](const std::string& element) {
      return lineText(lineNumber) + ": " + element;
    };
    splitTokens(line, '#', tokens);
    if (tokens.empty()) continue;
    const string_view keyword = tokens[0];
    if (keyword == "v" || keyword == "vt" || keyword == "vn") {
      const bool isPosition = keyword == "v", isTexcoord = keyword == "vt";
      const auto element = [&]() {
        return isPosition
                   ? "vertex " + std::to_string(scan.positionLines.size())
                   : (isTexcoord ? "texture coordinate " + std::to_string(scan.texcoords.size() / 2)
                                 : std::string("normal"));
      };
      const size_t needed = isTexcoord ? 1 : 3;
      if (tokens.size() - 1 < needed) {
        fail(path, where(element()) + " has " + std::to_string(tokens.size() - 1) +
                       " values, expected at least " + std::to_string(needed));
      }
      double values[3] = {0.0, 0.0, 0.0};
      for (size_t k = 1; k < tokens.size(); ++k) {
        double value = 0.0;
        if (!parseDouble(tokens[k], value))
          fail(path, where(element()) + ": expected a number, got " + quoted(tokens[k]));
        if (k <= 3) values[k - 1] = value;
      }
      if (isPosition) {
        scan.positions.insert(scan.positions.end(), values, values + 3);
        scan.positionLines.push_back(lineNumber);
      } else if (isTexcoord) {
        scan.texcoords.insert(scan.texcoords.end(), values, values + 2);
      }
    } else if (keyword == "f") {
      const int polygon = static_cast<int>(scan.polygonLines.size());
      const auto element = [polygon]() { return "face " + std::to_string(polygon); };
      const size_t corners = tokens.size() - 1;
      if (corners < 3) {
        fail(path, where(element()) + " has " + std::to_string(corners) +
                       " corners, faces need at least 3");
      }
      if (corners > 255) {  // tinyobjloader stores corner counts in an unsigned char
        fail(path, where(element()) + " has " + std::to_string(corners) +
                       " corners, OBJ faces may have at most 255");
      }
      const long long positionsSoFar = static_cast<long long>(scan.positionLines.size());
      const long long texcoordsSoFar = static_cast<long long>(scan.texcoords.size() / 2);
      for (size_t k = 1; k < tokens.size(); ++k) {
        // Corner "v", "v/vt", "v//vn" or "v/vt/vn".
        parts.clear();
        string_view rest = tokens[k];
        for (size_t slash = rest.find('/'); slash != string_view::npos; slash = rest.find('/')) {
          parts.push_back(rest.substr(0, slash));
          rest.remove_prefix(slash + 1);
        }
        parts.push_back(rest);
        long long refs[3] = {0, 0, 0};
        bool bad = parts.size() > 3 || !parseInteger(parts[0], refs[0]);
        for (size_t p = 1; p < parts.size() && !bad; ++p)
          bad = !parts[p].empty() && !parseInteger(parts[p], refs[p]);
        if (bad) {
          fail(path, where(element()) + ": bad corner " + quoted(tokens[k]) +
                         ", expected v, v/vt, v//vn or v/vt/vn with integer indices");
        }
        for (int p = 0; p < 2; ++p) {
          const long long index = refs[p];
          if (p == 1 && (parts.size() < 2 || parts[1].empty())) continue;
          const long long soFar = p == 0 ? positionsSoFar : texcoordsSoFar;
          const char* what = p == 0 ? "vertex index " : "texture coordinate index ";
          if (index == 0)
            fail(path, where(element()) + ": " + what + "0 is invalid (OBJ indices start at 1)");
          if (index < 0 && soFar + index < 0) {
            fail(path, where(element()) + ": relative " + what + std::to_string(index) +
                           " points before the first element (" + std::to_string(soFar) +
                           " defined so far)");
          }
          if (index > soFar) pending.push_back({polygon, lineNumber, index, p == 1});
        }
      }
      if (groupOrMaterialSeen) scan.hasLabels = true;
      if (currentLabel < 0) {
        // Labels count distinct (group, material) pairs in order of first use.
        const auto inserted =
            labelIds.emplace(std::make_pair(group, material), static_cast<int>(labelIds.size()));
        currentLabel = inserted.first->second;
      }
      scan.polygonLines.push_back(lineNumber);
      scan.polygonCorners.push_back(static_cast<int>(corners));
      scan.polygonLabels.push_back(currentLabel);
    } else if (keyword == "g" || keyword == "o") {
      group.clear();
      for (size_t k = 1; k < tokens.size(); ++k) {
        if (k > 1) group += ' ';
        group.append(tokens[k]);
      }
      groupOrMaterialSeen = true;
      currentLabel = -1;
    } else if (keyword == "usemtl") {
      material = tokens.size() > 1 ? std::string(tokens[1]) : std::string();
      groupOrMaterialSeen = true;
      currentLabel = -1;
    }
    // Other statements (mtllib, s, l, p, vp, ...) carry nothing a surface needs.
  }
  const long long positionCount = static_cast<long long>(scan.positionLines.size());
  const long long texcoordCount = static_cast<long long>(scan.texcoords.size() / 2);
  for (const PendingIndex& p : pending) {
    const long long count = p.texcoord ? texcoordCount : positionCount;
    if (p.index > count) {
      fail(path, "face " + std::to_string(p.polygon) + " (" + lineText(p.line) +
                     "): " + (p.texcoord ? "texture coordinate index " : "vertex index ") +
                     std::to_string(p.index) + " out of range [1, " + std::to_string(count) + "]");
    }
  }
  return scan;
}

std::string trimmed(const std::string& s) {
  const size_t begin = s.find_first_not_of(" \t\r\n");
  if (begin == std::string::npos) return std::string();
  return s.substr(begin, s.find_last_not_of(" \t\r\n") - begin + 1);
}

TriangleMesh readObj(const std::string& text, const std::string& path, ElementOrigins& origins) {
  const ObjScan scan = scanObj(text, path);

  tinyobj::attrib_t attrib;
  std::vector<tinyobj::shape_t> shapes;
  std::vector<tinyobj::material_t> materials;
  std::string warnings, errors;
  // tinyobjloader rejects a comment after a face ("f 1 2 3 # c"); blank out
  // every comment so both parses see the same statements on the same lines.
  std::string uncommented = text;
  for (size_t hash = uncommented.find('#'); hash != std::string::npos;
       hash = uncommented.find('#', hash)) {
    for (; hash < uncommented.size() && uncommented[hash] != '\n' && uncommented[hash] != '\r';
         ++hash)
      uncommented[hash] = ' ';
  }
  std::istringstream stream(std::move(uncommented));
  // No material reader: labels come from `usemtl` names, not from .mtl files.
  const bool ok =
      tinyobj::LoadObj(&attrib, &shapes, &materials, &warnings, &errors, &stream, nullptr,
                       /*triangulate=*/false, /*default_vcols_fallback=*/false);
  if (!ok) fail(path, "tinyobjloader: " + trimmed(errors));
  const size_t positionCount = scan.positionLines.size();
  if (attrib.vertices.size() != 3 * positionCount ||
      attrib.texcoords.size() != scan.texcoords.size()) {
    fail(path, "tinyobjloader read " + std::to_string(attrib.vertices.size() / 3) +
                   " vertices where the line scan found " + std::to_string(positionCount) +
                   " (unsupported OBJ syntax?)");
  }

  const bool haveTexcoords = !scan.texcoords.empty();
  bool uvsConsistent = haveTexcoords;
  std::vector<double> uvs(haveTexcoords ? 2 * positionCount : 0, 0.0);
  std::vector<char> uvAssigned(haveTexcoords ? positionCount : 0, 0);
  std::vector<int> triangles, labels, corners;
  triangles.reserve(3 * scan.polygonLines.size());
  int polygon = 0;
  for (const tinyobj::shape_t& shape : shapes) {
    size_t corner = 0;
    for (const unsigned char cornerCount : shape.mesh.num_face_vertices) {
      const auto p = static_cast<size_t>(polygon);
      if (p >= scan.polygonLines.size() || scan.polygonCorners[p] != cornerCount) {
        fail(path, "tinyobjloader and the line scan disagree at face " + std::to_string(polygon) +
                       " (unsupported OBJ syntax?)");
      }
      corners.clear();
      for (size_t k = 0; k < cornerCount; ++k, ++corner) {
        const tinyobj::index_t& index = shape.mesh.indices[corner];
        corners.push_back(index.vertex_index);
        if (!uvsConsistent) continue;
        // One texture coordinate per position, or none at all (see mesh_io.h).
        const int t = index.texcoord_index;
        const auto v = static_cast<size_t>(index.vertex_index);
        // Both indices were range-checked by the scan; tinyobjloader resolves
        // them itself, so check again rather than trust the two to agree.
        if (t < 0 || static_cast<size_t>(t) >= scan.texcoords.size() / 2 || v >= positionCount) {
          uvsConsistent = false;
          continue;
        }
        const double u = scan.texcoords[2 * static_cast<size_t>(t)];
        const double w = scan.texcoords[2 * static_cast<size_t>(t) + 1];
        if (!uvAssigned[v]) {
          uvs[2 * v] = u;
          uvs[2 * v + 1] = w;
          uvAssigned[v] = 1;
        } else if (uvs[2 * v] != u || uvs[2 * v + 1] != w) {
          uvsConsistent = false;
        }
      }
      appendFan(corners, polygon, scan.polygonLines[p], scan.hasLabels, scan.polygonLabels[p],
                triangles, labels, origins);
      ++polygon;
    }
  }
  if (static_cast<size_t>(polygon) != scan.polygonLines.size()) {
    fail(path, "tinyobjloader read " + std::to_string(polygon) +
                   " faces where the line scan found " + std::to_string(scan.polygonLines.size()) +
                   " (unsupported OBJ syntax?)");
  }
  origins.vertexLines = scan.positionLines;
  if (!uvsConsistent) uvs.clear();
  return assembleMesh(scan.positions, triangles, std::move(labels), uvs);
}

// ---------------------------------------------------------------------------
// PLY

enum class PlyType { Int8, UInt8, Int16, UInt16, Int32, UInt32, Float32, Float64 };

bool plyTypeFromName(string_view name, PlyType& type) {
  static constexpr std::pair<const char*, PlyType> names[] = {
      {"char", PlyType::Int8},      {"int8", PlyType::Int8},       {"uchar", PlyType::UInt8},
      {"uint8", PlyType::UInt8},    {"short", PlyType::Int16},     {"int16", PlyType::Int16},
      {"ushort", PlyType::UInt16},  {"uint16", PlyType::UInt16},   {"int", PlyType::Int32},
      {"int32", PlyType::Int32},    {"uint", PlyType::UInt32},     {"uint32", PlyType::UInt32},
      {"float", PlyType::Float32},  {"float32", PlyType::Float32}, {"double", PlyType::Float64},
      {"float64", PlyType::Float64}};
  for (const auto& [typeName, value] : names) {
    if (name == typeName) {
      type = value;
      return true;
    }
  }
  return false;
}

size_t plyTypeSize(PlyType type) {
  switch (type) {
    case PlyType::Int8:
    case PlyType::UInt8:
      return 1;
    case PlyType::Int16:
    case PlyType::UInt16:
      return 2;
    case PlyType::Int32:
    case PlyType::UInt32:
    case PlyType::Float32:
      return 4;
    case PlyType::Float64:
      return 8;
  }
  return 0;
}

bool plyTypeIsInteger(PlyType type) { return type != PlyType::Float32 && type != PlyType::Float64; }

struct PlyProperty {
  std::string name;
  PlyType type = PlyType::Float32;  ///< Item type for lists.
  bool isList = false;
  PlyType countType = PlyType::UInt8;
};

struct PlyElement {
  std::string name;
  long long count = 0;
  std::vector<PlyProperty> properties;
};

struct PlyHeader {
  bool binary = false;
  std::vector<PlyElement> elements;
  size_t dataOffset = 0;  ///< Byte offset of the first data byte.
  int headerLines = 0;    ///< Lines up to and including end_header.
};

/// Which element and property indices hold the data we read (-1: absent).
struct PlyLayout {
  int vertexElement = -1, faceElement = -1;
  int x = -1, y = -1, z = -1, u = -1, v = -1;
  int indices = -1, label = -1;
};

PlyHeader parsePlyHeader(string_view text, const std::string& path) {
  PlyHeader header;
  LineReader lines(text);
  std::vector<string_view> tokens;
  string_view line;
  const auto bad = [&](const std::string& what) {
    fail(path, "bad PLY header (" + lineText(lines.lineNumber()) + "): " + what);
  };
  if (!lines.next(line)) bad("file is empty");
  splitTokens(line, '\0', tokens);
  if (tokens.size() != 1 || tokens[0] != "ply") bad("first line must be 'ply'");
  bool haveFormat = false;
  while (true) {
    if (!lines.next(line)) fail(path, "bad PLY header: no 'end_header' line");
    splitTokens(line, '\0', tokens);
    if (tokens.empty()) continue;
    const string_view keyword = tokens[0];
    if (keyword == "comment" || keyword == "obj_info") continue;
    if (keyword == "end_header") break;
    if (keyword == "format") {
      if (tokens.size() != 3) bad("expected 'format <ascii|binary_little_endian> 1.0'");
      if (tokens[1] == "binary_big_endian") {
        fail(path, lineText(lines.lineNumber()) +
                       ": binary_big_endian PLY is not supported; convert the file to "
                       "binary_little_endian or ascii");
      }
      if (tokens[1] != "ascii" && tokens[1] != "binary_little_endian")
        bad("unknown format " + quoted(tokens[1]));
      if (tokens[2] != "1.0") bad("unsupported PLY version " + quoted(tokens[2]));
      header.binary = tokens[1] != "ascii";
      haveFormat = true;
    } else if (keyword == "element") {
      long long count = 0;
      if (tokens.size() != 3 || !parseInteger(tokens[2], count) || count < 0 || count > INT_MAX)
        bad("expected 'element <name> <count>' with a count in [0, 2^31)");
      header.elements.push_back({std::string(tokens[1]), count, {}});
    } else if (keyword == "property") {
      if (header.elements.empty()) bad("property before any element");
      PlyProperty property;
      if (tokens.size() == 5 && tokens[1] == "list") {
        property.isList = true;
        if (!plyTypeFromName(tokens[2], property.countType) ||
            !plyTypeIsInteger(property.countType))
          bad("list count type " + quoted(tokens[2]) + " is not an integer type");
        if (!plyTypeFromName(tokens[3], property.type)) bad("unknown type " + quoted(tokens[3]));
        property.name = std::string(tokens[4]);
      } else if (tokens.size() == 3) {
        if (!plyTypeFromName(tokens[1], property.type)) bad("unknown type " + quoted(tokens[1]));
        property.name = std::string(tokens[2]);
      } else {
        bad("expected 'property <type> <name>' or 'property list <type> <type> <name>'");
      }
      header.elements.back().properties.push_back(std::move(property));
    } else {
      bad("unknown keyword " + quoted(keyword));
    }
  }
  if (!haveFormat) fail(path, "bad PLY header: no 'format' line");
  header.dataOffset = lines.offset();
  header.headerLines = lines.lineNumber();
  return header;
}

PlyLayout plyLayout(const PlyHeader& header, const std::string& path) {
  PlyLayout layout;
  const auto bad = [&](const std::string& what) { fail(path, "bad PLY header: " + what); };
  for (size_t e = 0; e < header.elements.size(); ++e) {
    const std::string& name = header.elements[e].name;
    if (name == "vertex" && layout.vertexElement < 0) layout.vertexElement = static_cast<int>(e);
    if (name == "face" && layout.faceElement < 0) layout.faceElement = static_cast<int>(e);
  }
  if (layout.vertexElement < 0) bad("no 'vertex' element");
  if (layout.faceElement < 0) bad("no 'face' element");

  const auto find = [](const PlyElement& element, const char* name) {
    for (size_t p = 0; p < element.properties.size(); ++p)
      if (element.properties[p].name == name) return static_cast<int>(p);
    return -1;
  };
  const PlyElement& vertex = header.elements[static_cast<size_t>(layout.vertexElement)];
  int* const coordinates[3] = {&layout.x, &layout.y, &layout.z};
  const char* const coordinateNames[3] = {"x", "y", "z"};
  for (int k = 0; k < 3; ++k) {
    *coordinates[k] = find(vertex, coordinateNames[k]);
    if (*coordinates[k] < 0)
      bad(std::string("element 'vertex' has no property '") + coordinateNames[k] + "'");
  }
  const char* const uvNames[4][2] = {
      {"u", "v"}, {"s", "t"}, {"texture_u", "texture_v"}, {"texture_s", "texture_t"}};
  for (const auto& names : uvNames) {
    const int u = find(vertex, names[0]), v = find(vertex, names[1]);
    if (u >= 0 && v >= 0) {
      layout.u = u;
      layout.v = v;
      break;
    }
  }
  for (const int p : {layout.x, layout.y, layout.z, layout.u, layout.v}) {
    if (p >= 0 && vertex.properties[static_cast<size_t>(p)].isList)
      bad("vertex property '" + vertex.properties[static_cast<size_t>(p)].name + "' is a list");
  }

  const PlyElement& face = header.elements[static_cast<size_t>(layout.faceElement)];
  layout.indices = find(face, "vertex_indices");
  if (layout.indices < 0) layout.indices = find(face, "vertex_index");
  if (layout.indices < 0)
    bad("element 'face' has no list property 'vertex_indices' or 'vertex_index'");
  const PlyProperty& indices = face.properties[static_cast<size_t>(layout.indices)];
  if (!indices.isList || !plyTypeIsInteger(indices.type))
    bad("face property '" + indices.name + "' must be a list of an integer type");
  layout.label = find(face, "label");
  if (layout.label >= 0) {
    const PlyProperty& label = face.properties[static_cast<size_t>(layout.label)];
    if (label.isList || !plyTypeIsInteger(label.type))
      bad("face property 'label' must be a scalar integer");
  }
  return layout;
}

std::string elementText(const PlyElement& element, long long index) {
  return element.name + " " + std::to_string(index);
}

/// ASCII PLY data: one element instance per line.
class PlyAsciiSource {
 public:
  PlyAsciiSource(string_view data, int linesBefore, const std::string& path)
      : lines_(data), linesBefore_(linesBefore), path_(path) {}

  void beginElement(const PlyElement& element, long long index) {
    string_view text;
    do {
      if (!lines_.next(text)) {
        fail(path_, "file ends after " + std::to_string(index) + " of the " +
                        std::to_string(element.count) + " '" + element.name +
                        "' elements declared in the header (" + lineText(line()) + ")");
      }
      splitTokens(text, '\0', tokens_);
    } while (tokens_.empty());
    next_ = 0;
  }

  double readReal(const PlyElement& element, long long index, const PlyProperty& property) {
    const string_view token = take(element, index, property);
    double value = 0.0;
    if (!parseDouble(token, value)) {
      fail(path_, lineText(line()) + ": " + elementText(element, index) + ", property '" +
                      property.name + "': expected a number, got " + quoted(token));
    }
    return value;
  }

  long long readInteger(const PlyElement& element, long long index, const PlyProperty& property) {
    const string_view token = take(element, index, property);
    long long value = 0;
    if (!parseInteger(token, value)) {
      fail(path_, lineText(line()) + ": " + elementText(element, index) + ", property '" +
                      property.name + "': expected an integer, got " + quoted(token));
    }
    return value;
  }

  void endElement(const PlyElement& element, long long index) {
    if (next_ < tokens_.size()) {
      fail(path_, lineText(line()) + ": " + elementText(element, index) + " has " +
                      std::to_string(tokens_.size()) +
                      " values, more than its properties declare " +
                      "(do the counts in the header match the data?)");
    }
  }

  void finish(const PlyHeader& header) {
    string_view text;
    while (lines_.next(text)) {
      splitTokens(text, '\0', tokens_);
      if (!tokens_.empty()) {
        std::string counts;
        for (const PlyElement& element : header.elements)
          counts += (counts.empty() ? "" : ", ") + std::to_string(element.count) + " '" +
                    element.name + "'";
        fail(path_, lineText(line()) + ": data after the last element the header declares (" +
                        counts + "); the counts in the header do not match the data");
      }
    }
  }

  /// 1-based line in the file of the current element.
  int line() const { return linesBefore_ + lines_.lineNumber(); }

 private:
  string_view take(const PlyElement& element, long long index, const PlyProperty& property) {
    if (next_ >= tokens_.size()) {
      fail(path_, lineText(line()) + ": " + elementText(element, index) +
                      " has too few values (property '" + property.name + "' is missing)");
    }
    return tokens_[next_++];
  }

  LineReader lines_;
  int linesBefore_;
  const std::string& path_;
  std::vector<string_view> tokens_;
  size_t next_ = 0;
};

/// Binary little-endian PLY data, decoded byte by byte so that the host's
/// byte order does not matter.
class PlyBinarySource {
 public:
  PlyBinarySource(string_view data, const std::string& path) : data_(data), path_(path) {}

  void beginElement(const PlyElement&, long long) {}
  void endElement(const PlyElement&, long long) {}
  int line() const { return 0; }

  double readReal(const PlyElement& element, long long index, const PlyProperty& property,
                  PlyType type) {
    const std::uint64_t bits = load(element, index, property, plyTypeSize(type));
    switch (type) {
      case PlyType::Float32: {
        const auto narrow = static_cast<std::uint32_t>(bits);
        float value = 0.0f;
        std::memcpy(&value, &narrow, sizeof value);
        return value;
      }
      case PlyType::Float64: {
        double value = 0.0;
        std::memcpy(&value, &bits, sizeof value);
        return value;
      }
      default:
        return static_cast<double>(toInteger(bits, type));
    }
  }

  long long readInteger(const PlyElement& element, long long index, const PlyProperty& property,
                        PlyType type) {
    return toInteger(load(element, index, property, plyTypeSize(type)), type);
  }

  void finish(const PlyHeader&) {
    if (pos_ != data_.size()) {
      fail(path_, std::to_string(data_.size() - pos_) +
                      " bytes of binary data after the last element the header declares; the "
                      "counts in the header do not match the data");
    }
  }

 private:
  static long long toInteger(std::uint64_t bits, PlyType type) {
    switch (type) {
      case PlyType::Int8:
        return static_cast<std::int8_t>(bits);
      case PlyType::UInt8:
        return static_cast<std::uint8_t>(bits);
      case PlyType::Int16:
        return static_cast<std::int16_t>(bits);
      case PlyType::UInt16:
        return static_cast<std::uint16_t>(bits);
      case PlyType::Int32:
        return static_cast<std::int32_t>(bits);
      case PlyType::UInt32:
        return static_cast<std::uint32_t>(bits);
      default:
        return 0;  // float types never reach here (checked in the header)
    }
  }

  std::uint64_t load(const PlyElement& element, long long index, const PlyProperty& property,
                     size_t size) {
    if (data_.size() - pos_ < size) {
      fail(path_, "truncated binary data: the file ends inside " + elementText(element, index) +
                      " of " + std::to_string(element.count) + " (property '" + property.name +
                      "', byte " + std::to_string(pos_) + " of the data)");
    }
    std::uint64_t bits = 0;
    for (size_t b = 0; b < size; ++b)
      bits |= static_cast<std::uint64_t>(static_cast<unsigned char>(data_[pos_ + b])) << (8 * b);
    pos_ += size;
    return bits;
  }

  string_view data_;
  const std::string& path_;
  size_t pos_ = 0;
};

// The two sources share one element loop; the type argument only matters to
// the binary source (ASCII tokens carry their own spelling).
double readPlyReal(PlyAsciiSource& s, const PlyElement& e, long long i, const PlyProperty& p,
                   PlyType) {
  return s.readReal(e, i, p);
}
double readPlyReal(PlyBinarySource& s, const PlyElement& e, long long i, const PlyProperty& p,
                   PlyType t) {
  return s.readReal(e, i, p, t);
}
long long readPlyInteger(PlyAsciiSource& s, const PlyElement& e, long long i, const PlyProperty& p,
                         PlyType) {
  return s.readInteger(e, i, p);
}
long long readPlyInteger(PlyBinarySource& s, const PlyElement& e, long long i, const PlyProperty& p,
                         PlyType t) {
  return s.readInteger(e, i, p, t);
}

template <class Source>
long long readPlyListCount(Source& source, const PlyElement& element, long long index,
                           const PlyProperty& property, const std::string& path) {
  const long long count = readPlyInteger(source, element, index, property, property.countType);
  if (count < 0) {
    fail(path, (source.line() > 0 ? lineText(source.line()) + ": " : std::string()) +
                   elementText(element, index) + ", property '" + property.name +
                   "': negative list length " + std::to_string(count));
  }
  return count;
}

template <class Source>
TriangleMesh readPlyBody(Source& source, const PlyHeader& header, const PlyLayout& layout,
                         size_t dataBytes, const std::string& path, ElementOrigins& origins) {
  const auto& vertexElement = header.elements[static_cast<size_t>(layout.vertexElement)];
  const long long vertexCount = vertexElement.count;
  const bool hasUVs = layout.u >= 0;
  const bool hasLabels = layout.label >= 0;
  // Reserve no more than the data could hold, so a corrupt count cannot ask for gigabytes.
  const auto capped = [&](long long count) {
    return static_cast<size_t>(
        std::min<long long>(count, static_cast<long long>(dataBytes / 2 + 1)));
  };
  std::vector<double> positions, uvs;
  std::vector<int> triangles, labels, corners;
  positions.reserve(3 * capped(vertexCount));
  if (hasUVs) uvs.reserve(2 * capped(vertexCount));
  triangles.reserve(3 * capped(header.elements[static_cast<size_t>(layout.faceElement)].count));

  for (size_t e = 0; e < header.elements.size(); ++e) {
    const PlyElement& element = header.elements[e];
    const bool isVertex = static_cast<int>(e) == layout.vertexElement;
    const bool isFace = static_cast<int>(e) == layout.faceElement;
    for (long long i = 0; i < element.count; ++i) {
      source.beginElement(element, i);
      double xyz[3] = {0.0, 0.0, 0.0}, uv[2] = {0.0, 0.0};
      int label = 0;
      for (size_t p = 0; p < element.properties.size(); ++p) {
        const PlyProperty& property = element.properties[p];
        const int pi = static_cast<int>(p);
        if (isFace && pi == layout.indices) {
          const long long count = readPlyListCount(source, element, i, property, path);
          if (count < 3) {
            fail(path, (source.line() > 0 ? lineText(source.line()) + ": " : std::string()) +
                           "face " + std::to_string(i) + " has " + std::to_string(count) +
                           " corners, faces need at least 3");
          }
          corners.clear();
          for (long long k = 0; k < count; ++k) {
            const long long index = readPlyInteger(source, element, i, property, property.type);
            if (index < 0 || index >= vertexCount) {
              fail(path,
                   "face " + std::to_string(i) +
                       (source.line() > 0 ? " (" + lineText(source.line()) + ")" : std::string()) +
                       ": vertex index " + std::to_string(index) + " out of range [0, " +
                       std::to_string(vertexCount - 1) + "]");
            }
            corners.push_back(static_cast<int>(index));
          }
        } else if (property.isList) {
          const long long count = readPlyListCount(source, element, i, property, path);
          for (long long k = 0; k < count; ++k)
            readPlyReal(source, element, i, property, property.type);
        } else if (isFace && pi == layout.label) {
          const long long value = readPlyInteger(source, element, i, property, property.type);
          if (value < INT_MIN || value > INT_MAX)
            fail(path, "face " + std::to_string(i) + ": label " + std::to_string(value) +
                           " out of int range");
          label = static_cast<int>(value);
        } else {
          const double value = readPlyReal(source, element, i, property, property.type);
          if (isVertex) {
            if (pi == layout.x) xyz[0] = value;
            if (pi == layout.y) xyz[1] = value;
            if (pi == layout.z) xyz[2] = value;
            if (pi == layout.u) uv[0] = value;
            if (pi == layout.v) uv[1] = value;
          }
        }
      }
      source.endElement(element, i);
      if (isVertex) {
        positions.insert(positions.end(), xyz, xyz + 3);
        if (hasUVs) uvs.insert(uvs.end(), uv, uv + 2);
        if (source.line() > 0) origins.vertexLines.push_back(source.line());
      } else if (isFace) {
        appendFan(corners, static_cast<int>(i), source.line(), hasLabels, label, triangles, labels,
                  origins);
      }
    }
  }
  source.finish(header);
  return assembleMesh(positions, triangles, std::move(labels), uvs);
}

TriangleMesh readPly(const std::string& text, const std::string& path, ElementOrigins& origins) {
  const PlyHeader header = parsePlyHeader(text, path);
  const PlyLayout layout = plyLayout(header, path);
  const string_view data = string_view(text).substr(header.dataOffset);
  if (header.binary) {
    PlyBinarySource source(data, path);
    return readPlyBody(source, header, layout, data.size(), path, origins);
  }
  PlyAsciiSource source(data, header.headerLines, path);
  return readPlyBody(source, header, layout, data.size(), path, origins);
}

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
    appendFan(corners, static_cast<int>(f), lines.lineNumber(), false, 0, triangles, labels,
              origins);
  }
  if (nextData()) fail(path, at() + "data after the last face" + countsNote);
  return assembleMesh(positions, triangles, std::move(labels), {});
}

std::string lowercaseExtension(const std::string& path) {
  const size_t slash = path.find_last_of("/\\");
  const size_t dot = path.find_last_of('.');
  if (dot == std::string::npos || (slash != std::string::npos && dot < slash)) return std::string();
  std::string extension = path.substr(dot);
  for (char& c : extension) c = static_cast<char>(std::tolower(static_cast<unsigned char>(c)));
  return extension;
}

void appendNumber(std::string& out, double value) {
  char buffer[32];
  // Shortest representation that reads back to the same double.
  const auto result = std::to_chars(buffer, buffer + sizeof buffer, value);
  out.append(buffer, static_cast<size_t>(result.ptr - buffer));
}

}  // namespace

TriangleMesh loadMesh(const std::string& path) {
  const std::string extension = lowercaseExtension(path);
  if (extension != ".obj" && extension != ".ply" && extension != ".off") {
    fail(path, (extension.empty() ? std::string("no file extension")
                                  : "unknown mesh file extension " + quoted(extension)) +
                   "; expected .obj, .ply or .off");
  }
  return parseMesh(readFile(path), extension, path);
}

TriangleMesh parseMesh(const std::string& text, const std::string& format,
                       const std::string& sourceName) {
  const std::string extension = lowercaseExtension("." + format);
  if (extension != ".obj" && extension != ".ply" && extension != ".off")
    fail(sourceName, "unknown mesh format " + quoted(format) + "; expected obj, ply or off");
  if (text.find_first_not_of(" \t\r\n\f\v") == std::string::npos)
    fail(sourceName, "file is empty");
  ElementOrigins origins;
  TriangleMesh mesh = extension == ".obj"   ? readObj(text, sourceName, origins)
                      : extension == ".ply" ? readPly(text, sourceName, origins)
                                            : readOff(text, sourceName, origins);
  validateWithOrigins(mesh, sourceName, &origins);
  return mesh;
}

void validateMesh(const TriangleMesh& mesh, const std::string& sourceName) {
  validateWithOrigins(mesh, sourceName, nullptr);
}

void saveMeshPly(const TriangleMesh& mesh, const std::string& path) {
  const Eigen::Index vertexCount = mesh.vertexPositions.rows();
  const Eigen::Index faceCount = mesh.faces.rows();
  const bool hasLabels = !mesh.faceLabels.empty();
  const bool hasUVs = mesh.vertexUVs.rows() != 0;
  if (hasLabels && static_cast<Eigen::Index>(mesh.faceLabels.size()) != faceCount)
    fail(path, "cannot save: " + std::to_string(mesh.faceLabels.size()) + " face labels for " +
                   std::to_string(faceCount) + " faces");
  if (hasUVs && mesh.vertexUVs.rows() != vertexCount)
    fail(path, "cannot save: " + std::to_string(mesh.vertexUVs.rows()) +
                   " texture coordinates for " + std::to_string(vertexCount) + " vertices");

  std::string out = "ply\nformat ascii 1.0\ncomment written by blot::stain::saveMeshPly\n";
  out += "element vertex " + std::to_string(vertexCount) + "\n";
  out += "property double x\nproperty double y\nproperty double z\n";
  if (hasUVs) out += "property double u\nproperty double v\n";
  out += "element face " + std::to_string(faceCount) + "\n";
  out += "property list uchar int vertex_indices\n";
  if (hasLabels) out += "property int label\n";
  out += "end_header\n";
  out.reserve(out.size() + static_cast<size_t>(vertexCount) * (hasUVs ? 100 : 60) +
              static_cast<size_t>(faceCount) * 32);
  for (Eigen::Index v = 0; v < vertexCount; ++v) {
    for (int k = 0; k < 3; ++k) {
      if (k > 0) out += ' ';
      appendNumber(out, mesh.vertexPositions(v, k));
    }
    for (int k = 0; hasUVs && k < 2; ++k) {
      out += ' ';
      appendNumber(out, mesh.vertexUVs(v, k));
    }
    out += '\n';
  }
  for (Eigen::Index f = 0; f < faceCount; ++f) {
    out += "3 " + std::to_string(mesh.faces(f, 0)) + " " + std::to_string(mesh.faces(f, 1)) + " " +
           std::to_string(mesh.faces(f, 2));
    if (hasLabels) out += " " + std::to_string(mesh.faceLabels[static_cast<size_t>(f)]);
    out += '\n';
  }

  try {
    writeFileAtomically(path, out.data(), out.size());
  } catch (const std::runtime_error& e) {
    throw MeshError(e.what());  // "<path>: cannot write ..."
  }
}

}  // namespace blot::stain
