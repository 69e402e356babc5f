// Headless software rasterizer for previews.
//
// Design note: docs/design-notes.md, "engine/outputs/src/renderer.cpp".
#include <blot/engine/renderer.h>

#include <blot/engine/color_space.h>

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <limits>
#include <stdexcept>
#include <string>

namespace blot::engine {
namespace {

constexpr double kPi = 3.14159265358979323846;
constexpr int kSubpixelBits = 8;
constexpr double kSubpixelScale = 1 << kSubpixelBits;
constexpr std::int64_t kSampleCenterOffset = 1 << (kSubpixelBits - 1);
// Side clip planes sit at this multiple of the half image size.
constexpr double kGuardBand = 2.0;
constexpr int kMaxPolygon = 9;  // a triangle clipped by five planes has at most 8 corners

struct CameraBasis {
  Eigen::Vector3d right, up, forward;
};

CameraBasis cameraBasis(const Camera& camera) {
  Eigen::Vector3d forward = camera.target - camera.eye;
  const double length = forward.norm();
  if (!(length > 0.0) || !std::isfinite(length)) {
    throw std::invalid_argument("Camera: eye and target must be finite and distinct");
  }
  forward /= length;
  Eigen::Vector3d upHint = camera.up;
  Eigen::Vector3d right = forward.cross(upHint);
  if (!(right.norm() > 1e-9 * upHint.norm())) {
    // Up is parallel to the view (or zero): use the axis least aligned with it.
    Eigen::Index axis = 0;
    forward.cwiseAbs().minCoeff(&axis);
    upHint = Eigen::Vector3d::Unit(axis);
    right = forward.cross(upHint);
  }
  right.normalize();
  return CameraBasis{right, right.cross(forward), forward};
}

double perspectiveTan(const Camera& camera) {
  if (!(camera.verticalFovDegrees > 0.0 && camera.verticalFovDegrees < 180.0)) {
    throw std::invalid_argument("Camera: verticalFovDegrees must be in (0, 180), got " +
                                std::to_string(camera.verticalFovDegrees));
  }
  return std::tan(0.5 * camera.verticalFovDegrees * kPi / 180.0);
}

// Pixels (or samples) per unit of x/d (perspective) or x (orthographic).
double projectionScale(const Camera& camera, int imageHeight) {
  if (camera.projection == Projection::Perspective) {
    return 0.5 * imageHeight / perspectiveTan(camera);
  }
  if (!(camera.orthographicHeight > 0.0)) {
    throw std::invalid_argument("Camera: orthographicHeight must be positive");
  }
  return imageHeight / camera.orthographicHeight;
}

// Samples are linear; the image holds sRGB bytes (color_space.h).
std::uint8_t toByte(double value) { return linearToSrgbByte(value); }

// Inside half-space a . (x, y, d) + b >= 0 in view coordinates.
struct ClipPlane {
  Eigen::Vector3d a;
  double b;
  double eval(const Eigen::Vector3d& view) const { return a.dot(view) + b; }
};

bool isTopLeft(std::int64_t dx, std::int64_t dy) {
  // Edges of a triangle with positive area in y-down coordinates.
  return dy < 0 || (dy == 0 && dx > 0);
}

}  // namespace

struct Renderer::ClipVertex {
  Eigen::Vector3d view;    // x right, y up, d forward (metres)
  Eigen::Vector3d color;
  Eigen::Vector3d normal;  // world, not normalised
  bool edgeToNextIsReal;   // edge from this vertex to the next polygon corner is a mesh edge
};

struct Renderer::RasterTriangle {
  ClipVertex vertex[3];
  Eigen::Vector3d faceNormal;  // world, unit
};

namespace {

// Frames the points given by pointAt(0 .. count-1) (all of which lie in `box`).
template <typename PointAt>
Camera framePointSet(const Eigen::AlignedBox3d& box, int count, const PointAt& pointAt,
                     const Eigen::Vector3d& viewDirection, double aspect, Projection projection,
                     const Eigen::Vector3d& up, double verticalFovDegrees, double margin) {
  if (box.isEmpty() || count == 0) throw std::invalid_argument("framing: no points");
  if (!(aspect > 0.0) || !(margin >= 1.0)) {
    throw std::invalid_argument("framing: aspect must be > 0 and margin >= 1");
  }
  Camera camera;
  camera.projection = projection;
  camera.verticalFovDegrees = verticalFovDegrees;
  camera.up = up;
  const Eigen::Vector3d center = box.center();
  camera.target = center;
  camera.eye = center - viewDirection;
  const CameraBasis basis = cameraBasis(camera);
  const double radius = std::max(0.5 * box.diagonal().norm(), 1e-12);

  if (projection == Projection::Orthographic) {
    double minX = std::numeric_limits<double>::infinity(), maxX = -minX;
    double minY = minX, maxY = -minX;
    for (int k = 0; k < count; ++k) {
      const Eigen::Vector3d q = pointAt(k) - center;
      minX = std::min(minX, basis.right.dot(q));
      maxX = std::max(maxX, basis.right.dot(q));
      minY = std::min(minY, basis.up.dot(q));
      maxY = std::max(maxY, basis.up.dot(q));
    }
    // Centre on the projected extent, not the 3D centre: tight for any view.
    camera.target = center + basis.right * (0.5 * (minX + maxX)) + basis.up * (0.5 * (minY + maxY));
    const double halfWidth = 0.5 * (maxX - minX);
    const double halfHeight = 0.5 * (maxY - minY);
    camera.orthographicHeight = 2.0 * margin * std::max({halfHeight, halfWidth / aspect, 1e-12});
    camera.eye = camera.target - basis.forward * (2.0 * radius);
    return camera;
  }
  // Perspective: the eye sits at distance D behind the centre; a point with
  // view offsets (x, y, z) needs D + z >= |x| / tanH and >= |y| / tanV.
  const double tanV = perspectiveTan(camera) / margin;
  const double tanH = tanV * aspect;
  double distance = 0.0;
  double minZ = std::numeric_limits<double>::infinity();
  for (int k = 0; k < count; ++k) {
    const Eigen::Vector3d q = pointAt(k) - center;
    const double z = basis.forward.dot(q);
    minZ = std::min(minZ, z);
    distance = std::max({distance, std::abs(basis.right.dot(q)) / tanH - z,
                         std::abs(basis.up.dot(q)) / tanV - z});
  }
  distance = std::max(distance, 1e-6 * radius - minZ);
  camera.eye = center - basis.forward * distance;
  camera.nearDistance = std::max(0.5 * (distance + minZ), 1e-4 * distance);
  return camera;
}

}  // namespace

Camera frameBoundingBox(const Eigen::AlignedBox3d& box, const Eigen::Vector3d& viewDirection,
                        double aspect, Projection projection, const Eigen::Vector3d& up,
                        double verticalFovDegrees, double margin) {
  const auto corner = [&box](int k) {
    return Eigen::Vector3d(box.corner(static_cast<Eigen::AlignedBox3d::CornerType>(k)));
  };
  return framePointSet(box, box.isEmpty() ? 0 : 8, corner, viewDirection, aspect, projection, up,
                       verticalFovDegrees, margin);
}

Camera framePoints(const stain::RowVectors3& points, const Eigen::Vector3d& viewDirection,
                   double aspect, Projection projection, const Eigen::Vector3d& up,
                   double verticalFovDegrees, double margin) {
  const auto point = [&points](int k) { return Eigen::Vector3d(points.row(k).transpose()); };
  return framePointSet(boundingBox(points), static_cast<int>(points.rows()), point, viewDirection,
                       aspect, projection, up, verticalFovDegrees, margin);
}

Eigen::AlignedBox3d boundingBox(const stain::RowVectors3& points) {
  Eigen::AlignedBox3d box;
  for (Eigen::Index i = 0; i < points.rows(); ++i) box.extend(points.row(i).transpose());
  return box;
}

Eigen::Vector3d projectToImage(const Camera& camera, int width, int height,
                               const Eigen::Vector3d& point) {
  const CameraBasis basis = cameraBasis(camera);
  const Eigen::Vector3d offset = point - camera.eye;
  const double x = basis.right.dot(offset);
  const double y = basis.up.dot(offset);
  const double d = basis.forward.dot(offset);
  const double scale = projectionScale(camera, height);
  const double divisor = camera.projection == Projection::Perspective ? d : 1.0;
  return {0.5 * width + scale * x / divisor, 0.5 * height - scale * y / divisor, d};
}

Renderer::Renderer(const RenderSettings& settings) : settings_(settings) {
  if (settings.width < 1 || settings.height < 1 || settings.width > kMaxImageSide ||
      settings.height > kMaxImageSide) {
    throw std::invalid_argument("Renderer: image size must be in 1.." + std::to_string(kMaxImageSide) + ", got " +
                                std::to_string(settings.width) + " x " +
                                std::to_string(settings.height));
  }
  if (settings.supersampling < 1 || settings.supersampling > kMaxSupersampling) {
    throw std::invalid_argument("Renderer: supersampling must be in 1.." + std::to_string(kMaxSupersampling) +
                                ", got " + std::to_string(settings.supersampling));
  }
  if (!(settings.lightDirection.norm() > 0.0)) {
    throw std::invalid_argument("Renderer: lightDirection must be non-zero");
  }
  const double sampleCount = static_cast<double>(settings.width) * settings.height *
                             settings.supersampling * settings.supersampling;
  if (sampleCount > kMaxImageSamples) {
    throw std::invalid_argument("Renderer: width x height x supersampling^2 must be at most "
                                "2^26 samples (16 bytes each)");
  }
  sampleWidth_ = settings.width * settings.supersampling;
  sampleHeight_ = settings.height * settings.supersampling;
}

void Renderer::checkInFrame() const {
  if (!inFrame_) throw std::logic_error("Renderer: draw called before beginFrame");
}

void Renderer::beginFrame(const Camera& camera) {
  const CameraBasis basis = cameraBasis(camera);
  camera_ = camera;
  right_ = basis.right;
  up_ = basis.up;
  forward_ = basis.forward;
  projectionScaleX_ = projectionScale(camera, sampleHeight_);
  projectionScaleY_ = projectionScaleX_;
  const Eigen::Vector3d light = settings_.lightDirection.normalized();
  lightWorld_ = settings_.lightInCameraFrame
                    ? Eigen::Vector3d(right_ * light.x() + up_ * light.y() - forward_ * light.z())
                    : light;
  const std::size_t sampleCount =
      static_cast<std::size_t>(sampleWidth_) * static_cast<std::size_t>(sampleHeight_);
  sampleColors_.resize(3 * sampleCount);
  sampleDepths_.assign(sampleCount, -std::numeric_limits<float>::infinity());
  for (std::size_t s = 0; s < sampleCount; ++s) {
    for (int c = 0; c < 3; ++c) {
      sampleColors_[3 * s + c] = static_cast<float>(settings_.background[c]);
    }
  }
  inFrame_ = true;
}

float Renderer::depthKey(double viewDepth) const {
  return camera_.projection == Projection::Perspective ? static_cast<float>(1.0 / viewDepth)
                                                       : static_cast<float>(-viewDepth);
}

void Renderer::writeSample(int index, float key, const Color& color) {
  sampleDepths_[index] = key;
  for (int c = 0; c < 3; ++c) sampleColors_[3 * index + c] = static_cast<float>(color[c]);
}

void Renderer::drawMesh(const stain::RowVectors3& vertexPositions, const stain::Triangles& faces,
                        const Eigen::MatrixX3d& vertexColors, const SurfaceStyle& style) {
  if (vertexColors.rows() != vertexPositions.rows()) {
    throw std::invalid_argument("Renderer::drawMesh: " + std::to_string(vertexColors.rows()) +
                                " colours for " + std::to_string(vertexPositions.rows()) +
                                " vertices");
  }
  drawMeshImpl(vertexPositions, faces, &vertexColors, Color::Zero(), style);
}

void Renderer::drawMesh(const stain::RowVectors3& vertexPositions, const stain::Triangles& faces,
                        const Color& color, const SurfaceStyle& style) {
  drawMeshImpl(vertexPositions, faces, nullptr, color, style);
}

void Renderer::drawMeshImpl(const stain::RowVectors3& vertexPositions,
                            const stain::Triangles& faces, const Eigen::MatrixX3d* vertexColors,
                            const Color& uniformColor, const SurfaceStyle& style) {
  checkInFrame();
  const Eigen::Index vertexCount = vertexPositions.rows();
  for (Eigen::Index f = 0; f < faces.rows(); ++f) {
    for (int k = 0; k < 3; ++k) {
      if (faces(f, k) < 0 || faces(f, k) >= vertexCount) {
        throw std::invalid_argument("Renderer::drawMesh: face " + std::to_string(f) +
                                    " index " + std::to_string(faces(f, k)) + " out of range");
      }
    }
  }
  viewPositions_.resize(vertexCount, 3);
  for (Eigen::Index i = 0; i < vertexCount; ++i) {
    const Eigen::Vector3d offset = vertexPositions.row(i).transpose() - camera_.eye;
    viewPositions_.row(i) << right_.dot(offset), up_.dot(offset), forward_.dot(offset);
  }
  if (style.smoothShading) {
    // Area-weighted vertex normals: the sum of unnormalised face cross products.
    vertexNormals_.setZero(vertexCount, 3);
    for (Eigen::Index f = 0; f < faces.rows(); ++f) {
      const Eigen::Vector3d p0 = vertexPositions.row(faces(f, 0));
      const Eigen::Vector3d cross = (Eigen::Vector3d(vertexPositions.row(faces(f, 1))) - p0)
                                        .cross(Eigen::Vector3d(vertexPositions.row(faces(f, 2))) - p0);
      for (int k = 0; k < 3; ++k) vertexNormals_.row(faces(f, k)) += cross.transpose();
    }
  }

  const bool perspective = camera_.projection == Projection::Perspective;
  const double halfW = 0.5 * sampleWidth_ * kGuardBand;
  const double halfH = 0.5 * sampleHeight_ * kGuardBand;
  const double s = projectionScaleX_;
  ClipPlane planes[5];
  int planeCount = 0;
  if (perspective) {
    planes[planeCount++] = {Eigen::Vector3d(0, 0, 1), -camera_.nearDistance};
    planes[planeCount++] = {Eigen::Vector3d(-s, 0, halfW), 0.0};
    planes[planeCount++] = {Eigen::Vector3d(s, 0, halfW), 0.0};
    planes[planeCount++] = {Eigen::Vector3d(0, -s, halfH), 0.0};
    planes[planeCount++] = {Eigen::Vector3d(0, s, halfH), 0.0};
  } else {
    planes[planeCount++] = {Eigen::Vector3d(-s, 0, 0), halfW};
    planes[planeCount++] = {Eigen::Vector3d(s, 0, 0), halfW};
    planes[planeCount++] = {Eigen::Vector3d(0, -s, 0), halfH};
    planes[planeCount++] = {Eigen::Vector3d(0, s, 0), halfH};
  }

  const Color magenta(1.0, 0.0, 1.0);
  ClipVertex polygon[kMaxPolygon];
  ClipVertex clipped[kMaxPolygon];
  for (Eigen::Index f = 0; f < faces.rows(); ++f) {
    RasterTriangle triangle;
    const Eigen::Vector3d p0 = vertexPositions.row(faces(f, 0));
    const Eigen::Vector3d faceCross = (Eigen::Vector3d(vertexPositions.row(faces(f, 1))) - p0)
                                          .cross(Eigen::Vector3d(vertexPositions.row(faces(f, 2))) - p0);
    const double crossNorm = faceCross.norm();
    if (!(crossNorm > 0.0)) continue;  // degenerate or non-finite: nothing to see
    triangle.faceNormal = faceCross / crossNorm;
    bool allInside = true;
    for (int k = 0; k < 3; ++k) {
      const int v = faces(f, k);
      ClipVertex& corner = polygon[k];
      corner.view = viewPositions_.row(v).transpose();
      Color albedo = vertexColors != nullptr ? Color(vertexColors->row(v).transpose()) : uniformColor;
      if (!albedo.allFinite()) albedo = magenta;
      corner.color = albedo;
      corner.normal = style.smoothShading ? Eigen::Vector3d(vertexNormals_.row(v).transpose())
                                          : triangle.faceNormal;
      corner.edgeToNextIsReal = true;
      for (int p = 0; p < planeCount; ++p) {
        if (!(planes[p].eval(corner.view) >= 0.0)) allInside = false;
      }
    }
    if (allInside) {
      for (int k = 0; k < 3; ++k) triangle.vertex[k] = polygon[k];
      rasterizeTriangle(triangle, style);
      continue;
    }
    // Sutherland-Hodgman against each plane; edge flags follow the surviving
    // pieces of original edges, edges on a clip plane are not mesh edges.
    int count = 3;
    for (int p = 0; p < planeCount && count > 0; ++p) {
      int outCount = 0;
      for (int k = 0; k < count; ++k) {
        const ClipVertex& a = polygon[k];
        const ClipVertex& b = polygon[(k + 1) % count];
        const double fa = planes[p].eval(a.view);
        const double fb = planes[p].eval(b.view);
        const bool aIn = fa >= 0.0;
        const bool bIn = fb >= 0.0;
        if (aIn) clipped[outCount++] = a;
        if (aIn != bIn) {
          const double t = fa / (fa - fb);
          ClipVertex cut;
          cut.view = a.view + t * (b.view - a.view);
          cut.color = a.color + t * (b.color - a.color);
          cut.normal = a.normal + t * (b.normal - a.normal);
          cut.edgeToNextIsReal = aIn ? false : a.edgeToNextIsReal;
          clipped[outCount++] = cut;
        }
      }
      count = outCount;
      for (int k = 0; k < count; ++k) polygon[k] = clipped[k];
    }
    // Fan-triangulate; inner diagonals are not mesh edges.
    for (int k = 1; k + 1 < count; ++k) {
      triangle.vertex[0] = polygon[0];
      triangle.vertex[1] = polygon[k];
      triangle.vertex[2] = polygon[k + 1];
      triangle.vertex[0].edgeToNextIsReal = k == 1 && polygon[0].edgeToNextIsReal;
      triangle.vertex[1].edgeToNextIsReal = polygon[k].edgeToNextIsReal;
      triangle.vertex[2].edgeToNextIsReal = k + 2 == count && polygon[k + 1].edgeToNextIsReal;
      rasterizeTriangle(triangle, style);
    }
  }
}

void Renderer::rasterizeTriangle(const RasterTriangle& triangle, const SurfaceStyle& style) {
  const bool perspective = camera_.projection == Projection::Perspective;
  // Screen positions in fixed point (1/256 sample), vertex order possibly swapped.
  int order[3] = {0, 1, 2};
  std::int64_t X[3], Y[3];
  for (int k = 0; k < 3; ++k) {
    const Eigen::Vector3d& view = triangle.vertex[k].view;
    const double divisor = perspective ? view.z() : 1.0;
    const double sx = 0.5 * sampleWidth_ + projectionScaleX_ * view.x() / divisor;
    const double sy = 0.5 * sampleHeight_ - projectionScaleY_ * view.y() / divisor;
    X[k] = std::llround(sx * kSubpixelScale);
    Y[k] = std::llround(sy * kSubpixelScale);
  }
  std::int64_t area = (X[1] - X[0]) * (Y[2] - Y[0]) - (Y[1] - Y[0]) * (X[2] - X[0]);
  if (area == 0) return;
  // A counter-clockwise (front-facing) triangle has negative area in y-down
  // coordinates; swap two corners so the edge functions are positive inside.
  const bool backFacing = area > 0;
  if (area < 0) {
    std::swap(order[1], order[2]);
    std::swap(X[1], X[2]);
    std::swap(Y[1], Y[2]);
    area = -area;
  }
  // realEdge[k]: the edge opposite corner k is a mesh edge.
  bool realEdge[3];
  {
    // In original order the edge opposite corner k starts at corner (k + 1) % 3.
    bool original[3];
    for (int k = 0; k < 3; ++k) original[k] = triangle.vertex[(k + 1) % 3].edgeToNextIsReal;
    for (int k = 0; k < 3; ++k) realEdge[k] = original[order[k]];
  }
  const ClipVertex* corner[3] = {&triangle.vertex[order[0]], &triangle.vertex[order[1]],
                                 &triangle.vertex[order[2]]};

  const std::int64_t minX = std::min({X[0], X[1], X[2]});
  const std::int64_t maxX = std::max({X[0], X[1], X[2]});
  const std::int64_t minY = std::min({Y[0], Y[1], Y[2]});
  const std::int64_t maxY = std::max({Y[0], Y[1], Y[2]});
  // Sample (i, j) has its centre at fixed-point (256 i + 128, 256 j + 128).
  const auto firstSample = [](std::int64_t lowest) {
    return static_cast<int>(std::max(0.0, std::ceil((lowest - kSampleCenterOffset) / kSubpixelScale)));
  };
  const auto lastSample = [](std::int64_t highest, int count) {
    return static_cast<int>(
        std::min(count - 1.0, std::floor((highest - kSampleCenterOffset) / kSubpixelScale)));
  };
  const int i0 = firstSample(minX);
  const int i1 = lastSample(maxX, sampleWidth_);
  const int j0 = firstSample(minY);
  const int j1 = lastSample(maxY, sampleHeight_);
  if (i0 > i1 || j0 > j1) return;

  // Edge k runs from corner (k+1)%3 to (k+2)%3 (opposite corner k).
  std::int64_t stepX[3], stepY[3], rowStart[3];
  bool topLeft[3];
  double inverseEdgeLength[3];
  const std::int64_t startX = static_cast<std::int64_t>(i0) * (1 << kSubpixelBits) + kSampleCenterOffset;
  const std::int64_t startY = static_cast<std::int64_t>(j0) * (1 << kSubpixelBits) + kSampleCenterOffset;
  for (int k = 0; k < 3; ++k) {
    const int a = (k + 1) % 3;
    const int b = (k + 2) % 3;
    const std::int64_t dx = X[b] - X[a];
    const std::int64_t dy = Y[b] - Y[a];
    stepX[k] = -dy * (1 << kSubpixelBits);
    stepY[k] = dx * (1 << kSubpixelBits);
    rowStart[k] = dx * (startY - Y[a]) - dy * (startX - X[a]);
    topLeft[k] = isTopLeft(dx, dy);
    // Distance in samples = w / (|e| * 256): w is in fixed units squared.
    inverseEdgeLength[k] =
        1.0 / (std::sqrt(static_cast<double>(dx) * dx + static_cast<double>(dy) * dy) * kSubpixelScale);
  }

  const double inverseArea = 1.0 / static_cast<double>(area);
  const double halfWire = 0.5 * style.wireframeWidth * settings_.supersampling;
  const double depth[3] = {corner[0]->view.z(), corner[1]->view.z(), corner[2]->view.z()};
  const bool flipNormal = backFacing && settings_.twoSidedLighting;

  for (int j = j0; j <= j1; ++j) {
    std::int64_t w[3] = {rowStart[0], rowStart[1], rowStart[2]};
    for (int i = i0; i <= i1; ++i) {
      bool inside = true;
      for (int k = 0; k < 3; ++k) {
        if (w[k] < 0 || (w[k] == 0 && !topLeft[k])) inside = false;
      }
      if (inside) {
        const double lambda[3] = {w[0] * inverseArea, w[1] * inverseArea, w[2] * inverseArea};
        double key = 0.0;
        double weight[3];
        if (perspective) {
          double inverseDepth = 0.0;
          for (int k = 0; k < 3; ++k) inverseDepth += lambda[k] / depth[k];
          for (int k = 0; k < 3; ++k) weight[k] = lambda[k] / depth[k] / inverseDepth;
          key = inverseDepth;
        } else {
          double viewDepth = 0.0;
          for (int k = 0; k < 3; ++k) viewDepth += lambda[k] * depth[k];
          for (int k = 0; k < 3; ++k) weight[k] = lambda[k];
          key = -viewDepth;
        }
        const float depthKeyValue = static_cast<float>(key);
        const int index = j * sampleWidth_ + i;
        if (depthKeyValue > sampleDepths_[index]) {
          bool onWire = false;
          if (style.wireframe) {
            for (int k = 0; k < 3; ++k) {
              if (realEdge[k] && w[k] * inverseEdgeLength[k] < halfWire) onWire = true;
            }
          }
          Color color;
          if (onWire) {
            color = style.wireframeColor;
          } else {
            Eigen::Vector3d normal = weight[0] * corner[0]->normal + weight[1] * corner[1]->normal +
                                     weight[2] * corner[2]->normal;
            const double length = normal.norm();
            normal = length > 1e-300 ? Eigen::Vector3d(normal / length) : triangle.faceNormal;
            if (flipNormal) normal = -normal;
            const double shade =
                settings_.ambient + settings_.diffuse * std::max(0.0, normal.dot(lightWorld_));
            color = (weight[0] * corner[0]->color + weight[1] * corner[1]->color +
                     weight[2] * corner[2]->color) *
                    shade;
          }
          writeSample(index, depthKeyValue, color);
        }
      }
      for (int k = 0; k < 3; ++k) w[k] += stepX[k];
    }
    for (int k = 0; k < 3; ++k) rowStart[k] += stepY[k];
  }
}

void Renderer::drawPolyline(const stain::RowVectors3& points, const LineStyle& style) {
  checkInFrame();
  if (points.rows() < 2) {
    throw std::invalid_argument("Renderer::drawPolyline: need at least 2 points, got " +
                                std::to_string(points.rows()));
  }
  for (Eigen::Index k = 0; k + 1 < points.rows(); ++k) {
    drawSegment(points.row(k).transpose(), points.row(k + 1).transpose(), style);
  }
}

void Renderer::drawPoints(const stain::RowVectors3& points, const LineStyle& style) {
  checkInFrame();
  for (Eigen::Index k = 0; k < points.rows(); ++k) drawDisc(points.row(k).transpose(), style);
}

void Renderer::drawSegment(const Eigen::Vector3d& a, const Eigen::Vector3d& b,
                           const LineStyle& style) {
  const bool perspective = camera_.projection == Projection::Perspective;
  const auto toView = [&](const Eigen::Vector3d& p) {
    const Eigen::Vector3d offset = p - camera_.eye;
    return Eigen::Vector3d(right_.dot(offset), up_.dot(offset), forward_.dot(offset));
  };
  Eigen::Vector3d va = toView(a);
  Eigen::Vector3d vb = toView(b);
  if (!va.allFinite() || !vb.allFinite()) return;
  if (perspective) {
    const double nearD = camera_.nearDistance;
    if (va.z() < nearD && vb.z() < nearD) return;
    if (va.z() < nearD) va = va + (nearD - va.z()) / (vb.z() - va.z()) * (vb - va);
    if (vb.z() < nearD) vb = vb + (nearD - vb.z()) / (va.z() - vb.z()) * (va - vb);
  }
  const auto toSample = [&](const Eigen::Vector3d& view) {
    const double divisor = perspective ? view.z() : 1.0;
    return Eigen::Vector2d(0.5 * sampleWidth_ + projectionScaleX_ * view.x() / divisor,
                           0.5 * sampleHeight_ - projectionScaleY_ * view.y() / divisor);
  };
  const Eigen::Vector2d sa = toSample(va);
  const Eigen::Vector2d sb = toSample(vb);
  const auto biasedKey = [&](double viewDepth) {
    const double biased = viewDepth - style.depthBias;
    return depthKey(perspective ? std::max(biased, 0.5 * camera_.nearDistance) : biased);
  };
  const double keyA = biasedKey(va.z());
  const double keyB = biasedKey(vb.z());
  const double half = 0.5 * style.width * settings_.supersampling;
  const Eigen::Vector2d direction = sb - sa;
  const double lengthSquared = direction.squaredNorm();
  const int i0 = std::max(0, static_cast<int>(std::floor(std::min(sa.x(), sb.x()) - half)));
  const int i1 = std::min(sampleWidth_ - 1, static_cast<int>(std::ceil(std::max(sa.x(), sb.x()) + half)));
  const int j0 = std::max(0, static_cast<int>(std::floor(std::min(sa.y(), sb.y()) - half)));
  const int j1 = std::min(sampleHeight_ - 1, static_cast<int>(std::ceil(std::max(sa.y(), sb.y()) + half)));
  for (int j = j0; j <= j1; ++j) {
    for (int i = i0; i <= i1; ++i) {
      const Eigen::Vector2d p(i + 0.5, j + 0.5);
      const double t =
          lengthSquared > 0.0 ? std::min(1.0, std::max(0.0, (p - sa).dot(direction) / lengthSquared))
                              : 0.0;
      if ((p - (sa + t * direction)).norm() > half) continue;
      const auto key = static_cast<float>(keyA + t * (keyB - keyA));
      const int index = j * sampleWidth_ + i;
      if (style.depthTest && !(key > sampleDepths_[index])) continue;
      if (style.depthTest) {
        writeSample(index, key, style.color);
      } else {
        for (int c = 0; c < 3; ++c) sampleColors_[3 * index + c] = static_cast<float>(style.color[c]);
      }
    }
  }
}

void Renderer::drawDisc(const Eigen::Vector3d& center, const LineStyle& style) {
  drawSegment(center, center, style);
}

Image Renderer::finishFrame() const {
  checkInFrame();
  const int n = settings_.supersampling;
  Image image(settings_.width, settings_.height, 3);
  const double inverseCount = 1.0 / (n * n);
  for (int y = 0; y < settings_.height; ++y) {
    std::uint8_t* row = image.row(y);
    for (int x = 0; x < settings_.width; ++x) {
      double sum[3] = {0.0, 0.0, 0.0};
      for (int sy = 0; sy < n; ++sy) {
        for (int sx = 0; sx < n; ++sx) {
          const std::size_t index = static_cast<std::size_t>(y * n + sy) * sampleWidth_ +
                                    static_cast<std::size_t>(x * n + sx);
          for (int c = 0; c < 3; ++c) sum[c] += sampleColors_[3 * index + c];
        }
      }
      for (int c = 0; c < 3; ++c) row[3 * x + c] = toByte(sum[c] * inverseCount);
    }
  }
  return image;
}

Image renderMesh(const stain::RowVectors3& vertexPositions, const stain::Triangles& faces,
                 const Eigen::MatrixX3d& vertexColors, const Camera& camera,
                 const RenderSettings& settings, const SurfaceStyle& style) {
  Renderer renderer(settings);
  renderer.beginFrame(camera);
  renderer.drawMesh(vertexPositions, faces, vertexColors, style);
  return renderer.finishFrame();
}

}  // namespace blot::engine
