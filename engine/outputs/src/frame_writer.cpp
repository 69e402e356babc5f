// What a headless run writes about an Engine: PLY frames, previews, the mass budget.
#include <blot/engine/frame_writer.h>

#include <cmath>
#include <filesystem>
#include <stdexcept>
#include <utility>

namespace blot::engine {

PlyFrame plyFrame(const Engine& e) {
  PlyFrame ply;
  ply.vertexPositions = e.positions();
  ply.faces = e.faces();
  // Normals and UVs first (after x y z) when the mesh has UVs; without UVs the file is as before.
  if (e.definition().mesh.vertexUVs.rows() == e.vertexCount() && e.vertexCount() > 0)
    ply.vertexAttributes = normalAndUvAttributes(e.normals(), e.definition().mesh.vertexUVs);
  for (PlyVertexAttribute a : {PlyVertexAttribute{"solvent", e.solvent(), PlyScalarType::Float32},
                               {"solute", e.solute(), PlyScalarType::Float32},
                               {"absorbed_solvent", e.absorbedSolvent(), PlyScalarType::Float32},
                               {"absorbed_solute", e.absorbedSolute(), PlyScalarType::Float32},
                               {"adsorbed_solute", e.adsorbedSolute(), PlyScalarType::Float32}})
    ply.vertexAttributes.push_back(a);
  for (auto& attribute : velocityAttributes(e.liquidWorldVelocities())) ply.vertexAttributes.push_back(attribute);
  for (auto& attribute : relativeVelocityAttributes(e.liquidVelocities())) ply.vertexAttributes.push_back(attribute);
  ply.vertexColors = vertexColorsToBytes(e.colors());
  return ply;
}

nlohmann::json massBudgetJson(const stain::MassBudget& budget) { return outputJson(budget); }

nlohmann::json statisticsJson(const EngineStatistics& statistics) {
  return outputJson(statistics, statistics.steps > 0 ? static_cast<double>(statistics.steps) : 1.0);
}

RenderSettings previewRenderSettings(const ScenePreview& p) {
  RenderSettings settings;
  settings.width = p.width;
  settings.height = p.height;
  settings.supersampling = p.supersampling;
  settings.background = {0.9, 0.91, 0.94};
  return settings;
}

Camera previewCamera(const ScenePreview& p, const stain::RowVectors3& positions) {
  const Eigen::Vector3d view = p.viewDirection.normalized();
  const Eigen::Vector3d up = p.up.norm() > 0                 ? p.up.normalized()
                             : std::abs(view.z()) < 0.9 ? Eigen::Vector3d::UnitZ()
                                                        : Eigen::Vector3d::UnitY();
  return framePoints(positions, view, double(p.width) / p.height, p.projection, up);
}

Image renderPreview(const Engine& engine, const ScenePreview& preview, PreviewShape shape,
                    const PreviewOverlay& overlay) {
  // The same colours on either shape: the rest shape shows the stain as it
  // will look on the flat cloth.
  const stain::RowVectors3& positions =
      shape == PreviewShape::Rest ? engine.definition().mesh.vertexPositions : engine.positions();
  Renderer renderer(previewRenderSettings(preview));
  renderer.beginFrame(previewCamera(preview, positions));
  renderer.drawMesh(positions, engine.faces(), engine.colors());
  if (overlay) overlay(renderer);
  return renderer.finishFrame();
}

FrameWriter::FrameWriter(const Engine& engine, FrameWriterOptions options)
    : engine_(engine), options_(std::move(options)), ply_(options_.directory, options_.name, options_.ply) {
  if (options_.name.empty()) throw std::invalid_argument("FrameWriter: empty output name");
  // The name becomes file names in the directory, as a scene's "name" rule
  // (no folder in it: "../../escape" wrote outside the directory).
  if (options_.name.find_first_of("/\\") != std::string::npos || options_.name.front() == '.')
    throw std::invalid_argument("FrameWriter: output name \"" + options_.name +
                                "\" must be a file name (no '/' or '\\', not starting with '.')");
  std::filesystem::create_directories(options_.directory);
}

std::string FrameWriter::plyPath(int frame) const { return ply_.framePath(frame); }

std::string FrameWriter::writePly(int frame) const { return ply_.write(frame, plyFrame(engine_)); }

std::string FrameWriter::previewPath(PreviewShape shape) const {
  const std::string file = options_.name + (shape == PreviewShape::Rest ? "_rest.png" : ".png");
  return (std::filesystem::path(options_.directory) / file).string();
}

Image FrameWriter::renderPreview(PreviewShape shape, const PreviewOverlay& overlay) const {
  return engine::renderPreview(engine_, options_.preview, shape, overlay);
}

std::string FrameWriter::writePreview(PreviewShape shape) const {
  const std::string path = previewPath(shape);
  writePng(renderPreview(shape), path);
  return path;
}

}  // namespace blot::engine
