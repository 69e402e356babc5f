#pragma once
/// PLY frame caches: one file per frame with positions, triangles, any number of
/// named per-vertex scalar attributes and optional per-vertex colours, for
/// rendering elsewhere (Houdini, Blender, MeshLab) or for regression checks.
///
/// File layout (see docs/rendering.md):
///   element vertex #V: x y z (float or double), then each attribute in the
///     order given (float or double), then red green blue (uchar) if colours;
///   element face #F: property list uchar int vertex_indices (three per face).
/// Binary little-endian by default, ASCII on request. Writes are atomic
/// (temporary file + rename) and refuse non-finite values.
#include <blot/engine/output_options.h>
#include <blot/stain/types.h>

#include <Eigen/Core>

#include <cstdint>
#include <string>
#include <vector>

namespace blot::engine {

/// Scalar type written for a property (values are always given as double).
enum class PlyScalarType { Float32, Float64 };

/// One named per-vertex scalar, e.g. {"solute", sigmaS}. Names must be
/// non-empty, made of [A-Za-z0-9_], unique, and not one of x y z red green blue.
struct PlyVertexAttribute {
  std::string name;
  Eigen::VectorXd values;  ///< #V values, in whatever unit the attribute has (document it).
  PlyScalarType type = PlyScalarType::Float32;
};

/// Per-vertex colours, #V by 3, 0-255 (red, green, blue), or 0 rows for none.
using VertexColors8 = Eigen::Matrix<std::uint8_t, Eigen::Dynamic, 3>;

/// One frame's content. Positions and faces are required; the rest is optional.
struct PlyFrame {
  stain::RowVectors3 vertexPositions;  ///< #V by 3, metres.
  stain::Triangles faces;              ///< #F by 3 vertex indices in [0, #V).
  std::vector<PlyVertexAttribute> vertexAttributes;
  VertexColors8 vertexColors;          ///< #V by 3 or 0 rows.
};

struct PlyWriteOptions {
  PlyFormat format = PlyFormat::BinaryLittleEndian;
  PlyScalarType positionType = PlyScalarType::Float32;
  /// Free text written as `comment` header lines (one per line of text); may be empty.
  std::string comment;
};

/// The three attributes "vx", "vy", "vz" from a #V by 3 velocity array (m/s):
/// the engine writes the liquid's world velocity under these names.
std::vector<PlyVertexAttribute> velocityAttributes(const stain::RowVectors3& vertexVelocities,
                                                   PlyScalarType type = PlyScalarType::Float32);
/// The three attributes "rel_vx", "rel_vy", "rel_vz" (m/s): the engine writes
/// the liquid's velocity relative to the cloth (world axes) under these names.
std::vector<PlyVertexAttribute> relativeVelocityAttributes(const stain::RowVectors3& vertexVelocities,
                                                           PlyScalarType type = PlyScalarType::Float32);

/// The attributes "nx", "ny", "nz" (unit normals) and "u", "v" (texture
/// coordinates, v up) that DCC importers (Blender, MeshLab, Houdini) read as
/// normals and UVs; `blot run` writes them first, after x y z, when the mesh has UVs.
std::vector<PlyVertexAttribute> normalAndUvAttributes(const Eigen::MatrixX3d& vertexNormals,
                                                      const Eigen::MatrixX2d& vertexUVs,
                                                      PlyScalarType type = PlyScalarType::Float32);

/// Converts linear colours in [0, 1] (#V by 3, clamped; non-finite becomes 0)
/// to sRGB-encoded bytes, round(255 · srgbEncode(c)) (color_space.h): PLY
/// readers (Blender, MeshLab) take uchar colours as sRGB.
VertexColors8 vertexColorsToBytes(const Eigen::MatrixX3d& vertexColors);

/// Writes `frame` to `path` atomically. Throws std::invalid_argument when the
/// frame is malformed (attribute length != #V, bad or duplicate name, face index
/// out of range) or holds a non-finite value, naming the attribute (or x/y/z)
/// and the vertex index, e.g. "frame_0003.ply: attribute 'solute' vertex 17 is
/// nan"; a finite double that overflows float32 counts as infinite. Throws
/// std::runtime_error when the file cannot be written. Nothing is written on error.
void writePlyFrame(const std::string& path, const PlyFrame& frame,
                   const PlyWriteOptions& options = {});

/// Writes a numbered sequence: frame k goes to `<directory>/<prefix>_<k, 4+ digits>.ply`.
class PlyFrameWriter {
 public:
  /// The directory must exist; it is not created.
  PlyFrameWriter(std::string directory, std::string prefix = "frame",
                 PlyWriteOptions options = {});

  /// Path that frame `frameIndex` (>= 0) is written to.
  std::string framePath(int frameIndex) const;

  /// Writes frame `frameIndex` and returns its path (see writePlyFrame for errors).
  std::string write(int frameIndex, const PlyFrame& frame) const;

  const PlyWriteOptions& options() const { return options_; }

 private:
  std::string directory_;
  std::string prefix_;
  PlyWriteOptions options_;
};

}  // namespace blot::engine
