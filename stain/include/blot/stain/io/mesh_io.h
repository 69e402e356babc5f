#pragma once
/// Reading triangle meshes from OBJ, PLY (ASCII and binary little-endian) and OFF.
///
/// Every loader validates what it returns: finite coordinates, indices in range,
/// no repeated-vertex or zero-area faces, an edge- and vertex-manifold surface
/// with consistent orientation (via SurfaceTopology), at least one face.
/// Failures throw MeshError whose message starts with the file path and names
/// the line, face, edge or vertex at fault, e.g.
///   "bad.obj: face 12 (line 40): vertex index 97 out of range [1, 96]".
#include <blot/stain/geometry/triangle_mesh.h>

#include <string>

namespace blot::stain {

/// Loads `path`, choosing the format from its extension (.obj, .ply, .off;
/// case-insensitive). Polygons with more than three corners are fan-triangulated.
/// Polygon (c0, c1, ..., cn-1) becomes triangles (c0, ck, ck+1), k = 1..n-2, in
/// file order, each with the polygon's label.
/// PLY: reads `vertex` x,y,z (float/double), optional u,v / s,t, `face`
/// vertex_indices (or vertex_index) lists, and an optional int face property
/// `label`. OBJ: `g`/`o`/`usemtl` groups become face labels when present:
/// faceLabels is filled when any face follows a g, o or usemtl statement, and
/// each distinct (group-or-object name, material name) pair gets the next label
/// 0, 1, 2, ... in order of its first face (faces before any such statement get
/// the pair of empty names). OBJ `vt` become vertexUVs only when every face
/// corner has one and each position is always used with the same (u, v) values
/// (texture indices may differ from position indices); a mesh with UV seams
/// loads without UVs rather than being cut apart at the seams.
TriangleMesh loadMesh(const std::string& path);

/// Parses a mesh held in memory exactly as loadMesh parses a file: `format` is
/// "obj", "ply" or "off" (case-insensitive, a leading dot allowed), `text` the
/// file's bytes (binary PLY included), `sourceName` the name every message
/// starts with. Used by the fuzz targets (tests/fuzz) and for embedded meshes.
TriangleMesh parseMesh(const std::string& text, const std::string& format,
                       const std::string& sourceName);

/// Checks geometry and topology of an in-memory mesh; `sourceName` prefixes
/// every message (a path, or a description such as "generated grid").
/// Throws MeshError on the first problem found.
void validateMesh(const TriangleMesh& mesh, const std::string& sourceName);

/// Writes an ASCII PLY of positions and faces (and face labels and UVs when
/// present) with round-trip precision: loadMesh gives back the same doubles.
/// Writes `path`.tmp first and renames it, so readers never see a partial file.
void saveMeshPly(const TriangleMesh& mesh, const std::string& path);

}  // namespace blot::stain
