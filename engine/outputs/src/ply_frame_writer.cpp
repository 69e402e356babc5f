// PLY frame caches with named per-vertex attributes.
//
// Design note: a frame is validated completely (shapes, names, indices, every
// value finite in the type it is written as) before a single byte is produced,
// then serialised into one memory buffer and handed to an atomic write, so a
// bad value or a crash never leaves a partial or poisoned file behind. Binary
// output is assembled byte by byte from the IEEE bit patterns, which makes it
// little-endian on any host; ASCII output uses std::to_chars (shortest text
// that reads back to the same float/double, independent of the C locale).
// Rejected alternatives: writing with a PLY library (another dependency for
// ~200 lines, and none refuse NaN), and streaming straight to the file (a
// crash mid-frame leaves a truncated file with a valid-looking header).
#include <blot/engine/ply_frame_writer.h>

#include <blot/engine/color_space.h>

#include <blot/stain/io/atomic_file.h>

#include <algorithm>
#include <charconv>
#include <cmath>
#include <cstring>
#include <limits>
#include <set>
#include <sstream>
#include <stdexcept>
#include <system_error>
#include <utility>

namespace blot::engine {
namespace {

const char* plyTypeName(PlyScalarType type) {
  return type == PlyScalarType::Float32 ? "float" : "double";
}

bool isValidPropertyName(const std::string& name) {
  if (name.empty()) return false;
  for (char c : name) {
    const bool ok = (c >= 'a' && c <= 'z') || (c >= 'A' && c <= 'Z') || (c >= '0' && c <= '9') ||
                    c == '_';
    if (!ok) return false;
  }
  return true;
}

std::string describeBadValue(double value) {
  if (std::isnan(value)) return "nan";
  if (std::isinf(value)) return value > 0 ? "inf" : "-inf";
  std::ostringstream text;
  text << value << " (overflows float32)";
  return text.str();
}

bool isWritable(double value, PlyScalarType type) {
  if (!std::isfinite(value)) return false;
  return type == PlyScalarType::Float64 ||
         std::fabs(value) <= static_cast<double>(std::numeric_limits<float>::max());
}

void validateFrame(const std::string& path, const PlyFrame& frame, const PlyWriteOptions& options) {
  const Eigen::Index vertexCount = frame.vertexPositions.rows();
  const char* axisNames[3] = {"x", "y", "z"};
  for (Eigen::Index i = 0; i < vertexCount; ++i) {
    for (int k = 0; k < 3; ++k) {
      const double value = frame.vertexPositions(i, k);
      if (!isWritable(value, options.positionType)) {
        throw std::invalid_argument(path + ": position " + axisNames[k] + " vertex " +
                                    std::to_string(i) + " is " +
                                    describeBadValue(value));
      }
    }
  }
  std::set<std::string> names = {"x", "y", "z", "red", "green", "blue"};
  for (const PlyVertexAttribute& attribute : frame.vertexAttributes) {
    if (!isValidPropertyName(attribute.name)) {
      throw std::invalid_argument(path + ": attribute name '" + attribute.name +
                                  "' is not a valid PLY property name ([A-Za-z0-9_]+)");
    }
    if (!names.insert(attribute.name).second) {
      throw std::invalid_argument(path + ": attribute name '" + attribute.name +
                                  "' is used twice or clashes with x/y/z/red/green/blue");
    }
    if (attribute.values.size() != vertexCount) {
      throw std::invalid_argument(path + ": attribute '" + attribute.name + "' has " +
                                  std::to_string(attribute.values.size()) + " values for " +
                                  std::to_string(vertexCount) + " vertices");
    }
    for (Eigen::Index i = 0; i < vertexCount; ++i) {
      const double value = attribute.values[i];
      if (!isWritable(value, attribute.type)) {
        throw std::invalid_argument(path + ": attribute '" + attribute.name + "' vertex " +
                                    std::to_string(i) + " is " +
                                    describeBadValue(value));
      }
    }
  }
  if (frame.vertexColors.rows() != 0 && frame.vertexColors.rows() != vertexCount) {
    throw std::invalid_argument(path + ": " + std::to_string(frame.vertexColors.rows()) +
                                " vertex colours for " + std::to_string(vertexCount) +
                                " vertices");
  }
  for (Eigen::Index f = 0; f < frame.faces.rows(); ++f) {
    for (int k = 0; k < 3; ++k) {
      const int index = frame.faces(f, k);
      if (index < 0 || index >= vertexCount) {
        throw std::invalid_argument(path + ": face " + std::to_string(f) + " vertex index " +
                                    std::to_string(index) + " out of range [0, " +
                                    std::to_string(vertexCount) + ")");
      }
    }
  }
}

std::string headerText(const PlyFrame& frame, const PlyWriteOptions& options) {
  std::ostringstream header;
  header << "ply\n"
         << (options.format == PlyFormat::Ascii ? "format ascii 1.0\n"
                                                : "format binary_little_endian 1.0\n");
  header << "comment written by Blot (blot::engine::writePlyFrame)\n";
  std::istringstream commentLines(options.comment);
  for (std::string line; std::getline(commentLines, line);) header << "comment " << line << "\n";
  header << "element vertex " << frame.vertexPositions.rows() << "\n";
  for (const char* axis : {"x", "y", "z"}) {
    header << "property " << plyTypeName(options.positionType) << " " << axis << "\n";
  }
  for (const PlyVertexAttribute& attribute : frame.vertexAttributes) {
    header << "property " << plyTypeName(attribute.type) << " " << attribute.name << "\n";
  }
  if (frame.vertexColors.rows() != 0) {
    header << "property uchar red\nproperty uchar green\nproperty uchar blue\n";
  }
  header << "element face " << frame.faces.rows() << "\n"
         << "property list uchar int vertex_indices\n"
         << "end_header\n";
  return header.str();
}

// Little-endian serialisation from bit patterns: correct on any host byte order.
void appendUint32(std::vector<char>& out, std::uint32_t bits) {
  for (int b = 0; b < 4; ++b) out.push_back(static_cast<char>((bits >> (8 * b)) & 0xffu));
}

void appendUint64(std::vector<char>& out, std::uint64_t bits) {
  for (int b = 0; b < 8; ++b) out.push_back(static_cast<char>((bits >> (8 * b)) & 0xffu));
}

void appendBinaryScalar(std::vector<char>& out, double value, PlyScalarType type) {
  if (type == PlyScalarType::Float32) {
    const float narrow = static_cast<float>(value);
    std::uint32_t bits = 0;
    std::memcpy(&bits, &narrow, sizeof bits);
    appendUint32(out, bits);
  } else {
    std::uint64_t bits = 0;
    std::memcpy(&bits, &value, sizeof bits);
    appendUint64(out, bits);
  }
}

void appendText(std::vector<char>& out, const char* begin, const char* end) {
  out.insert(out.end(), begin, end);
}

void appendAsciiScalar(std::vector<char>& out, double value, PlyScalarType type) {
  char text[64];
  const std::to_chars_result result =
      type == PlyScalarType::Float32
          ? std::to_chars(text, text + sizeof text, static_cast<float>(value))
          : std::to_chars(text, text + sizeof text, value);
  appendText(out, text, result.ptr);
}

void appendAsciiInteger(std::vector<char>& out, long long value) {
  char text[32];
  const std::to_chars_result result = std::to_chars(text, text + sizeof text, value);
  appendText(out, text, result.ptr);
}

std::size_t scalarBytes(PlyScalarType type) { return type == PlyScalarType::Float32 ? 4 : 8; }

}  // namespace

std::vector<PlyVertexAttribute> velocityAttributes(const stain::RowVectors3& vertexVelocities,
                                                   PlyScalarType type) {
  return {PlyVertexAttribute{"vx", vertexVelocities.col(0), type},
          PlyVertexAttribute{"vy", vertexVelocities.col(1), type},
          PlyVertexAttribute{"vz", vertexVelocities.col(2), type}};
}

std::vector<PlyVertexAttribute> relativeVelocityAttributes(const stain::RowVectors3& vertexVelocities,
                                                           PlyScalarType type) {
  return {PlyVertexAttribute{"rel_vx", vertexVelocities.col(0), type},
          PlyVertexAttribute{"rel_vy", vertexVelocities.col(1), type},
          PlyVertexAttribute{"rel_vz", vertexVelocities.col(2), type}};
}

std::vector<PlyVertexAttribute> normalAndUvAttributes(const Eigen::MatrixX3d& vertexNormals,
                                                      const Eigen::MatrixX2d& vertexUVs, PlyScalarType type) {
  return {PlyVertexAttribute{"nx", vertexNormals.col(0), type}, PlyVertexAttribute{"ny", vertexNormals.col(1), type},
          PlyVertexAttribute{"nz", vertexNormals.col(2), type}, PlyVertexAttribute{"u", vertexUVs.col(0), type},
          PlyVertexAttribute{"v", vertexUVs.col(1), type}};
}

VertexColors8 vertexColorsToBytes(const Eigen::MatrixX3d& vertexColors) {
  VertexColors8 bytes(vertexColors.rows(), 3);
  for (Eigen::Index i = 0; i < vertexColors.rows(); ++i) {
    for (int k = 0; k < 3; ++k) {
      const double value = vertexColors(i, k);
      bytes(i, k) = linearToSrgbByte(std::isfinite(value) ? value : 0.0);
    }
  }
  return bytes;
}

void writePlyFrame(const std::string& path, const PlyFrame& frame,
                   const PlyWriteOptions& options) {
  validateFrame(path, frame, options);
  const std::string header = headerText(frame, options);
  const Eigen::Index vertexCount = frame.vertexPositions.rows();
  const bool hasColors = frame.vertexColors.rows() != 0;

  std::size_t vertexBytes = 3 * scalarBytes(options.positionType) + (hasColors ? 3 : 0);
  for (const PlyVertexAttribute& attribute : frame.vertexAttributes) {
    vertexBytes += scalarBytes(attribute.type);
  }
  std::vector<char> bytes;
  bytes.reserve(header.size() + static_cast<std::size_t>(vertexCount) * vertexBytes +
                static_cast<std::size_t>(frame.faces.rows()) * 13);
  appendText(bytes, header.data(), header.data() + header.size());

  if (options.format == PlyFormat::BinaryLittleEndian) {
    for (Eigen::Index i = 0; i < vertexCount; ++i) {
      for (int k = 0; k < 3; ++k) {
        appendBinaryScalar(bytes, frame.vertexPositions(i, k), options.positionType);
      }
      for (const PlyVertexAttribute& attribute : frame.vertexAttributes) {
        appendBinaryScalar(bytes, attribute.values[i], attribute.type);
      }
      if (hasColors) {
        for (int k = 0; k < 3; ++k) bytes.push_back(static_cast<char>(frame.vertexColors(i, k)));
      }
    }
    for (Eigen::Index f = 0; f < frame.faces.rows(); ++f) {
      bytes.push_back(3);
      for (int k = 0; k < 3; ++k) appendUint32(bytes, static_cast<std::uint32_t>(frame.faces(f, k)));
    }
  } else {
    for (Eigen::Index i = 0; i < vertexCount; ++i) {
      for (int k = 0; k < 3; ++k) {
        if (k > 0) bytes.push_back(' ');
        appendAsciiScalar(bytes, frame.vertexPositions(i, k), options.positionType);
      }
      for (const PlyVertexAttribute& attribute : frame.vertexAttributes) {
        bytes.push_back(' ');
        appendAsciiScalar(bytes, attribute.values[i], attribute.type);
      }
      if (hasColors) {
        for (int k = 0; k < 3; ++k) {
          bytes.push_back(' ');
          appendAsciiInteger(bytes, frame.vertexColors(i, k));
        }
      }
      bytes.push_back('\n');
    }
    for (Eigen::Index f = 0; f < frame.faces.rows(); ++f) {
      bytes.push_back('3');
      for (int k = 0; k < 3; ++k) {
        bytes.push_back(' ');
        appendAsciiInteger(bytes, frame.faces(f, k));
      }
      bytes.push_back('\n');
    }
  }
  stain::writeFileAtomically(path, bytes.data(), bytes.size());
}

PlyFrameWriter::PlyFrameWriter(std::string directory, std::string prefix, PlyWriteOptions options)
    : directory_(std::move(directory)), prefix_(std::move(prefix)), options_(std::move(options)) {}

std::string PlyFrameWriter::framePath(int frameIndex) const {
  if (frameIndex < 0) {
    throw std::invalid_argument("PlyFrameWriter: negative frame index " +
                                std::to_string(frameIndex));
  }
  std::string number = std::to_string(frameIndex);
  if (number.size() < 4) number.insert(0, 4 - number.size(), '0');
  std::string path = directory_;
  if (!path.empty() && path.back() != '/') path += '/';
  return path + prefix_ + "_" + number + ".ply";
}

std::string PlyFrameWriter::write(int frameIndex, const PlyFrame& frame) const {
  const std::string path = framePath(frameIndex);
  writePlyFrame(path, frame, options_);
  return path;
}

}  // namespace blot::engine
