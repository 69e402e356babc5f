// `blot mesh-info MESH [--render OUT.png]`: what a mesh is made of, as JSON.
//
// Design note: users bring scanned or modelled meshes, and the stain solver's
// accuracy depends on their quality: obtuse triangles and negative cotan
// weights are where P1 diffusion loses its maximum principle and the edge-wise
// connection Laplacian turns indefinite (DESIGN.md). So the summary reports
// those counts beside topology (Euler characteristic, boundary loops,
// components, genus) and size (area, bounding box, edge lengths), computed by
// the same stain/ functions the solver uses, not by a second implementation.
// The optional preview is the engine's software renderer, auto-framed.
#include "assets.h"
#include "commands.h"

#include <blot/engine/image.h>
#include <blot/engine/output_options.h>
#include <blot/engine/renderer.h>
#include <blot/stain/geometry/intrinsic_geometry.h>
#include <blot/stain/geometry/mesh_order.h>
#include <blot/stain/io/mesh_io.h>
#include <blot/stain/geometry/surface_topology.h>
#include <blot/stain/io/strict_json.h>

#include <nlohmann/json.hpp>

#include <algorithm>
#include <cmath>
#include <exception>
#include <iostream>
#include <memory>
#include <numeric>
#include <set>
#include <string>
#include <vector>

namespace blot::cli {
namespace {

constexpr double kPi = 3.14159265358979323846;

struct MeshInfoOptions {
  std::string meshPath;
  std::string renderPath;
  std::vector<double> view = {-0.35, -0.35, -1.0};
  std::vector<double> up = {0.0, 1.0, 0.0};
  int width = 800;
  int height = 600;
  bool wireframe = false;
};

// Connected components of the face graph (faces sharing a vertex), by union-find.
int connectedComponents(const stain::Triangles& faces, int vertexCount) {
  std::vector<int> parent(static_cast<std::size_t>(vertexCount));
  std::iota(parent.begin(), parent.end(), 0);
  const auto find = [&parent](int v) {
    while (parent[v] != v) {
      parent[v] = parent[parent[v]];
      v = parent[v];
    }
    return v;
  };
  for (Eigen::Index f = 0; f < faces.rows(); ++f) {
    for (int k = 1; k < 3; ++k) {
      const int a = find(faces(f, 0));
      const int b = find(faces(f, k));
      if (a != b) parent[std::max(a, b)] = std::min(a, b);
    }
  }
  int components = 0;
  for (int v = 0; v < vertexCount; ++v) components += find(v) == v ? 1 : 0;
  return components;
}

nlohmann::json rowJson(const Eigen::Vector3d& v) { return {v.x(), v.y(), v.z()}; }

Eigen::Vector3d vectorOption(const std::vector<double>& values, const char* name) {
  if (values.size() != 3) {
    throw std::invalid_argument(std::string("--") + name + " needs three numbers x,y,z");
  }
  return {values[0], values[1], values[2]};
}

// Median over face edges of |i − j|: how far apart in memory the solver
// finds a vertex's neighbours (each interior edge counted twice, once per face).
int medianEdgeSpan(const stain::Triangles& faces) {
  std::vector<int> spans;
  spans.reserve(static_cast<std::size_t>(3 * faces.rows()));
  for (Eigen::Index f = 0; f < faces.rows(); ++f)
    for (int c = 0; c < 3; ++c) spans.push_back(std::abs(faces(f, c) - faces(f, (c + 1) % 3)));
  if (spans.empty()) return 0;
  std::nth_element(spans.begin(), spans.begin() + static_cast<long>(spans.size() / 2), spans.end());
  return spans[spans.size() / 2];
}

/// How spread out the file's numbering is, against the locality order's
/// (scene key mesh.vertex_order, docs/scene-format.md); "locality_suggested"
/// where the file's spans are 8x the renumbered mesh's or more (the Table 1
/// bunny: 8,687 against 321, its stain step 0.7x as long renumbered).
nlohmann::json vertexOrderSummary(const stain::TriangleMesh& mesh) {
  stain::TriangleMesh renumbered = mesh;
  stain::reorderMesh(renumbered, stain::localityOrder(mesh));
  const int file = medianEdgeSpan(mesh.faces), locality = medianEdgeSpan(renumbered.faces);
  return {{"median_edge_index_span", file},
          {"median_edge_index_span_locality", locality},
          {"locality_suggested", file >= 8 * std::max(locality, 1)}};
}

nlohmann::json meshSummary(const std::string& path, const stain::TriangleMesh& mesh) {
  const int vertexCount = static_cast<int>(mesh.vertexPositions.rows());
  const stain::SurfaceTopology topology(mesh.faces, vertexCount, path);
  const stain::Vector lengths = stain::edgeLengths(topology, mesh.vertexPositions);
  const Eigen::MatrixX3d angles = stain::faceCornerAngles(topology, lengths);
  const stain::Vector areas = stain::faceAreas(topology, lengths);
  const stain::Vector weights = stain::edgeCotanWeights(topology, lengths, areas);

  int obtuse = 0;
  for (Eigen::Index f = 0; f < angles.rows(); ++f) obtuse += angles.row(f).maxCoeff() > 0.5 * kPi ? 1 : 0;
  const int negativeWeights = static_cast<int>((weights.array() < 0.0).count());
  const int components = connectedComponents(mesh.faces, vertexCount);
  const int loops = static_cast<int>(topology.boundaryLoops().size());
  const int euler = vertexCount - topology.edgeCount() + topology.faceCount();
  const Eigen::AlignedBox3d box = engine::boundingBox(mesh.vertexPositions);
  std::set<int> labels(mesh.faceLabels.begin(), mesh.faceLabels.end());

  nlohmann::json summary;
  summary["file"] = path;
  summary["vertices"] = vertexCount;
  summary["faces"] = topology.faceCount();
  summary["edges"] = topology.edgeCount();
  summary["boundary_loops"] = loops;
  summary["boundary_vertices"] =
      std::count(topology.vertexIsBoundary().begin(), topology.vertexIsBoundary().end(), 1);
  summary["components"] = components;
  summary["euler_characteristic"] = euler;
  // chi = sum over components of (2 - 2 g_c - b_c), orientable surfaces.
  summary["genus"] = (2 * components - euler - loops) / 2;
  summary["area"] = areas.sum();
  summary["bounding_box"] = {{"min", rowJson(box.min())},
                             {"max", rowJson(box.max())},
                             {"diagonal", box.diagonal().norm()}};
  summary["edge_length"] = {{"min", lengths.minCoeff()},
                            {"mean", lengths.mean()},
                            {"max", lengths.maxCoeff()}};
  summary["angle_degrees"] = {{"min", angles.minCoeff() * 180.0 / kPi},
                              {"max", angles.maxCoeff() * 180.0 / kPi}};
  summary["obtuse_triangles"] = obtuse;
  summary["negative_cotan_weight_edges"] = negativeWeights;
  summary["face_labels"] = labels.size();
  summary["has_uvs"] = mesh.vertexUVs.rows() == vertexCount && vertexCount > 0;
  summary["vertex_order"] = vertexOrderSummary(mesh);
  return summary;
}

constexpr int kPreviewSupersampling = 3;

void renderPreview(const MeshInfoOptions& options, const stain::TriangleMesh& mesh) {
  // Checked here as blot run's scene keys are: a zero, non-finite or huge
  // view failed as "Camera: eye and target must be finite and distinct", and
  // a bad --up was ignored silently.
  const Eigen::Vector3d view = vectorOption(options.view, "view"), up = vectorOption(options.up, "up");
  const auto finiteAndNonZero = [](const Eigen::Vector3d& v) {
    return v.allFinite() && v.cwiseAbs().maxCoeff() <= 1e6 && v.norm() > 0;
  };
  if (!finiteAndNonZero(view))
    throw std::invalid_argument("--view: expected a non-zero direction x,y,z with finite components of at most 1e6");
  if (!finiteAndNonZero(up) || !(up.cross(view).norm() > 1e-6 * up.norm() * view.norm()))
    throw std::invalid_argument("--up: expected a non-zero direction x,y,z not parallel to --view");
  engine::RenderSettings settings;
  settings.width = options.width;
  settings.height = options.height;
  settings.supersampling = kPreviewSupersampling;
  settings.background = {0.93, 0.94, 0.96};
  const engine::Camera camera = engine::framePoints(
      mesh.vertexPositions, view, static_cast<double>(options.width) / options.height, engine::Projection::Perspective,
      up);
  engine::SurfaceStyle style;
  style.wireframe = options.wireframe;
  style.wireframeWidth = 0.8;
  engine::Renderer renderer(settings);
  renderer.beginFrame(camera);
  renderer.drawMesh(mesh.vertexPositions, mesh.faces, engine::Color(0.72, 0.76, 0.84), style);
  engine::writePng(renderer.finishFrame(), options.renderPath);
}

int runMeshInfo(const MeshInfoOptions& options) {
  // The renderer's sample budget, checked before the mesh is read.
  const double samples = double(options.width) * options.height * kPreviewSupersampling * kPreviewSupersampling;
  if (!options.renderPath.empty() && samples > engine::kMaxImageSamples) {
    std::cerr << "blot mesh-info: error: --width " << options.width << " x --height " << options.height
              << ": the preview would take " << static_cast<long long>(samples) << " samples at supersampling "
              << kPreviewSupersampling << ", more than the renderer's limit of "
              << static_cast<long long>(engine::kMaxImageSamples) << " (at most "
              << static_cast<long long>(engine::kMaxImageSamples / (kPreviewSupersampling * kPreviewSupersampling))
              << " pixels)\n";
    return 1;
  }
  try {
    const stain::TriangleMesh mesh = stain::loadMesh(options.meshPath);
    nlohmann::json summary = meshSummary(options.meshPath, mesh);
    if (!options.renderPath.empty()) {
      renderPreview(options, mesh);
      summary["render"] = options.renderPath;
    }
    std::cout << stain::dumpJson(summary, 2) << "\n";
    return 0;
  } catch (const std::exception& error) {
    std::cerr << "blot mesh-info: error: " << error.what() << "\n";
    return 1;
  }
}

}  // namespace

void registerMeshInfoCommand(CLI::App& app, int& exitCode) {
  auto options = std::make_shared<MeshInfoOptions>();
  CLI::App* command = app.add_subcommand(
      "mesh-info", "Print a JSON summary of a mesh (topology, size, triangle quality); "
                   "optionally render a PNG preview");
  command->add_option("mesh", options->meshPath, "Mesh file (.obj, .ply, .off)")->required()->transform(assetPath());
  command->add_option("--render", options->renderPath, "Write a shaded PNG preview here");
  command->add_option("--view", options->view, "Preview view direction x,y,z (camera looks along it)")
      ->delimiter(',')
      ->expected(3);
  command->add_option("--up", options->up, "Preview up direction x,y,z")
      ->delimiter(',')
      ->expected(3);
  command->add_option("--width", options->width, "Preview width in pixels")
      ->check(CLI::Range(16, 8192));
  command->add_option("--height", options->height, "Preview height in pixels")
      ->check(CLI::Range(16, 8192));
  command->add_flag("--wireframe", options->wireframe, "Draw triangle edges in the preview");
  command->callback([options, &exitCode]() { exitCode = runMeshInfo(*options); });
}

}  // namespace blot::cli
