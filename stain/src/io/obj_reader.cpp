// The OBJ reader: our own line scan (line numbers, labels, index checks)
// cross-checked against tinyobjloader.
#include "mesh_text.h"

#include <tiny_obj_loader.h>

#include <map>
#include <sstream>
#include <utility>

namespace blot::stain::detail {
namespace {

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

}  // namespace

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
      appendPolygon(path, corners, scan.positions, polygon, scan.polygonLines[p], scan.hasLabels,
                    scan.polygonLabels[p], triangles, labels, origins);
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

}  // namespace blot::stain::detail
