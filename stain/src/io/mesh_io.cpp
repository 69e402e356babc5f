// Reading and writing triangle meshes: OBJ, PLY (ASCII, binary little-endian), OFF.
//
// Design note: docs/design-notes.md, "stain/src/io/mesh_io.cpp".
// The readers live in obj_reader.cpp, ply_reader.cpp and off_reader.cpp, the
// checks in mesh_validation.cpp, the helpers they share in mesh_text.h.
#include <blot/stain/io/mesh_io.h>

#include <blot/stain/io/atomic_file.h>

#include "mesh_text.h"

#include <cctype>
#include <charconv>
#include <string>

namespace blot::stain {

using detail::ElementOrigins;
using detail::fail;
using detail::quoted;
using detail::readFile;
using detail::readObj;
using detail::readOff;
using detail::readPly;
using detail::validateWithOrigins;

namespace {

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
  // A UTF-8 byte-order mark (editors on Windows write one) is not part of
  // the first statement: tinyobjloader would read "\xEF\xBB\xBFv" as an
  // unknown keyword and drop the first vertex. Line numbers are unchanged.
  std::string stripped;
  if (text.size() >= 3 && text.compare(0, 3, "\xEF\xBB\xBF") == 0) stripped = text.substr(3);
  const std::string& body = stripped.empty() ? text : stripped;
  if (body.find_first_not_of(" \t\r\n\f\v") == std::string::npos)
    fail(sourceName, "file is empty");
  ElementOrigins origins;
  TriangleMesh mesh = extension == ".obj"   ? readObj(body, sourceName, origins)
                      : extension == ".ply" ? readPly(body, sourceName, origins)
                                            : readOff(body, sourceName, origins);
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
