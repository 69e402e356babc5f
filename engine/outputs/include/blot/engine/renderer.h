#pragma once
/// Headless software rasterizer for previews: triangle meshes with per-vertex
/// colours, Lambert + ambient shading from one directional light, optional
/// wireframe, 3D polylines and points, supersampled anti-aliasing. No display,
/// GPU or global state; the same inputs give the same bytes.
///
/// Use: Renderer renderer(settings); renderer.beginFrame(camera);
/// renderer.drawMesh(...); renderer.drawPolyline(...); Image image = renderer.finishFrame();
/// Buffers are kept between frames, so a sequence of same-size frames allocates
/// only when a mesh grows.
#include <blot/engine/image.h>
#include <blot/engine/output_options.h>
#include <blot/stain/types.h>

#include <Eigen/Core>
#include <Eigen/Geometry>

#include <vector>

namespace blot::engine {

/// Linear colour, each channel in [0, 1]; written to images sRGB-encoded,
/// round(255 · srgbEncode(c)) (color_space.h).
using Color = Eigen::Vector3d;

/// A look-at camera. Screen x points along forward x up, screen y along up.
struct Camera {
  Eigen::Vector3d eye{0.0, 0.0, 1.0};     ///< Camera position, metres.
  Eigen::Vector3d target{0.0, 0.0, 0.0};  ///< Point seen at the image centre, metres.
  Eigen::Vector3d up{0.0, 1.0, 0.0};      ///< Approximate up; if parallel to the view, another axis is used.
  Projection projection = Projection::Perspective;
  double verticalFovDegrees = 30.0;  ///< Perspective: full vertical field of view, degrees in (0, 180).
  double orthographicHeight = 2.0;   ///< Orthographic: visible height at any depth, metres.
  double nearDistance = 1e-3;        ///< Perspective: geometry closer than this (metres) is clipped.
};

/// Camera looking along `viewDirection` at the box centre, far enough (or, for
/// orthographic, wide enough) that the whole box fits in an image of the given
/// aspect (width / height) with `margin` (>= 1) extra room. Perspective framing
/// fits all eight corners into the frustum exactly (then scales by margin).
Camera frameBoundingBox(const Eigen::AlignedBox3d& box, const Eigen::Vector3d& viewDirection,
                        double aspect, Projection projection = Projection::Perspective,
                        const Eigen::Vector3d& up = Eigen::Vector3d::UnitY(),
                        double verticalFovDegrees = 30.0, double margin = 1.08);

/// Like frameBoundingBox, but fits the #N by 3 points themselves (e.g. all
/// vertices of a mesh): tighter, since a box's corners usually stick out of
/// the shape. Looks at the points' bounding-box centre. O(N).
Camera framePoints(const stain::RowVectors3& points, const Eigen::Vector3d& viewDirection,
                   double aspect, Projection projection = Projection::Perspective,
                   const Eigen::Vector3d& up = Eigen::Vector3d::UnitY(),
                   double verticalFovDegrees = 30.0, double margin = 1.08);

/// Axis-aligned bounding box of #N by 3 points (empty box for no points).
Eigen::AlignedBox3d boundingBox(const stain::RowVectors3& points);

/// Where `point` lands in a width x height image: (x, y) in pixels (pixel (i, j)
/// covers [i, i+1) x [j, j+1), y down) and its view depth in metres (distance
/// along the view direction from the eye). Perspective points behind the eye
/// give a non-positive depth and meaningless x, y.
Eigen::Vector3d projectToImage(const Camera& camera, int width, int height,
                               const Eigen::Vector3d& point);

struct RenderSettings {
  int width = 800;   ///< Output pixels, 1..16384.
  int height = 600;  ///< Output pixels, 1..16384.
  /// Samples per pixel along each axis (1..4): n x n samples averaged per pixel.
  /// width x height x n^2 may not exceed 2^26 (16 bytes of buffers per sample).
  int supersampling = 2;
  Color background{1.0, 1.0, 1.0};
  /// Unit direction towards the light. In the camera frame (x right, y up, z
  /// towards the viewer) when lightInCameraFrame, else in world coordinates.
  Eigen::Vector3d lightDirection{-0.35, 0.5, 1.0};
  bool lightInCameraFrame = true;
  /// Shaded colour = albedo x (ambient + diffuse x max(0, n . l)).
  double ambient = 0.3;
  double diffuse = 0.7;
  /// When true, back faces are lit with the flipped normal (cloth has two sides).
  bool twoSidedLighting = true;
};

struct SurfaceStyle {
  /// Interpolate area-weighted vertex normals (true) or use face normals.
  bool smoothShading = true;
  bool wireframe = false;
  Color wireframeColor{0.12, 0.12, 0.12};
  /// Line width of the wireframe in output pixels.
  double wireframeWidth = 1.0;
};

struct LineStyle {
  Color color{0.85, 0.1, 0.1};
  /// Polyline width, or point diameter, in output pixels.
  double width = 2.0;
  /// When false the primitive is drawn on top of everything drawn before it.
  bool depthTest = true;
  /// Moves the primitive this many metres towards the camera for the depth
  /// test, so a path lying on a surface is not hidden by it.
  double depthBias = 0.0;
};

class Renderer {
 public:
  /// Throws std::invalid_argument on sizes or supersampling out of range.
  explicit Renderer(const RenderSettings& settings = {});

  const RenderSettings& settings() const { return settings_; }

  /// Starts a frame: clears to the background, empties the depth buffer.
  void beginFrame(const Camera& camera);

  /// Draws triangles (#F by 3 indices into #V by 3 positions, metres) with
  /// per-vertex albedo (#V by 3, [0, 1]); non-finite colours show as magenta.
  /// Throws std::invalid_argument on mismatched sizes or indices out of range.
  void drawMesh(const stain::RowVectors3& vertexPositions, const stain::Triangles& faces,
                const Eigen::MatrixX3d& vertexColors, const SurfaceStyle& style = {});
  /// Same with one albedo for the whole mesh.
  void drawMesh(const stain::RowVectors3& vertexPositions, const stain::Triangles& faces,
                const Color& color, const SurfaceStyle& style = {});

  /// Draws the path through #N by 3 points (N >= 2) as a screen-space line of
  /// style.width pixels with round joins, unshaded.
  void drawPolyline(const stain::RowVectors3& points, const LineStyle& style = {});
  /// Draws each of #N by 3 points as a disc of style.width pixels, unshaded.
  void drawPoints(const stain::RowVectors3& points, const LineStyle& style = {});

  /// Averages the samples into an RGB image (settings().width x height).
  Image finishFrame() const;

 private:
  struct ClipVertex;
  struct RasterTriangle;
  void checkInFrame() const;
  void drawMeshImpl(const stain::RowVectors3& vertexPositions, const stain::Triangles& faces,
                    const Eigen::MatrixX3d* vertexColors, const Color& uniformColor,
                    const SurfaceStyle& style);
  void rasterizeTriangle(const RasterTriangle& triangle, const SurfaceStyle& style);
  void drawSegment(const Eigen::Vector3d& a, const Eigen::Vector3d& b, const LineStyle& style);
  void drawDisc(const Eigen::Vector3d& center, const LineStyle& style);
  void writeSample(int index, float depthKey, const Color& color);
  float depthKey(double viewDepth) const;

  RenderSettings settings_;
  int sampleWidth_ = 0;
  int sampleHeight_ = 0;
  bool inFrame_ = false;
  // Camera frame for the current frame.
  Camera camera_;
  Eigen::Vector3d right_, up_, forward_, lightWorld_;
  double projectionScaleX_ = 1.0, projectionScaleY_ = 1.0;
  // Per-sample buffers: linear RGB and depth key (larger = nearer).
  std::vector<float> sampleColors_;
  std::vector<float> sampleDepths_;
  // Per-mesh scratch, reused between draws.
  stain::RowVectors3 viewPositions_;
  stain::RowVectors3 vertexNormals_;
};

/// One-call helper: a frame with a single mesh.
Image renderMesh(const stain::RowVectors3& vertexPositions, const stain::Triangles& faces,
                 const Eigen::MatrixX3d& vertexColors, const Camera& camera,
                 const RenderSettings& settings = {}, const SurfaceStyle& style = {});

}  // namespace blot::engine
