// Tests for the headless rasterizer: shading against the closed form,
// coverage, depth order, clipping, perspective-correct interpolation,
// wireframe, lines and points, framing, and determinism.
#include <blot/engine/renderer.h>
#include <blot/engine/color_space.h>

#include <gtest/gtest.h>

#include <cmath>
#include <cstdlib>

namespace blot::engine {
namespace {

// One byte is 1/255; shaded colours are compared within that.
constexpr int kByteTolerance = 1;
constexpr double kPi = 3.14159265358979323846;

// Shading is linear; images hold sRGB bytes (color_space.h).
Rgba8 toRgba(const Color& color) {
  return Rgba8{linearToSrgbByte(color.x()), linearToSrgbByte(color.y()), linearToSrgbByte(color.z()), 255};
}

void expectNear(Rgba8 actual, Rgba8 expected, int tolerance, const std::string& where) {
  EXPECT_LE(std::abs(actual.r - expected.r), tolerance) << where;
  EXPECT_LE(std::abs(actual.g - expected.g), tolerance) << where;
  EXPECT_LE(std::abs(actual.b - expected.b), tolerance) << where;
}

Camera frontOrthographic() {
  Camera camera;
  camera.eye = {0.0, 0.0, 5.0};
  camera.target = {0.0, 0.0, 0.0};
  camera.up = {0.0, 1.0, 0.0};
  camera.projection = Projection::Orthographic;
  camera.orthographicHeight = 2.0;
  return camera;
}

// Counter-clockwise seen from +z, i.e. facing a camera on the +z axis.
stain::RowVectors3 trianglePositions(double z) {
  stain::RowVectors3 positions(3, 3);
  positions << -0.8, -0.6, z, 0.8, -0.6, z, 0.0, 0.8, z;
  return positions;
}

stain::Triangles oneTriangle() {
  stain::Triangles faces(1, 3);
  faces << 0, 1, 2;
  return faces;
}

Rgba8 pixelAt(const Image& image, const Camera& camera, const Eigen::Vector3d& point) {
  const Eigen::Vector3d p = projectToImage(camera, image.width(), image.height(), point);
  return image.pixel(static_cast<int>(std::floor(p.x())), static_cast<int>(std::floor(p.y())));
}

RenderSettings smallSettings() {
  RenderSettings settings;
  settings.width = 64;
  settings.height = 64;
  settings.supersampling = 2;
  settings.background = {0.1, 0.2, 0.3};
  settings.lightDirection = {0.6, 0.0, 0.8};  // camera frame: n.l = 0.8 for a facing triangle
  settings.ambient = 0.3;
  settings.diffuse = 0.7;
  return settings;
}

TEST(Renderer, FrontFacingTriangleHasClosedFormShadeAndBackgroundOutside) {
  const RenderSettings settings = smallSettings();
  const Camera camera = frontOrthographic();
  const Color albedo(0.8, 0.4, 0.2);
  Renderer renderer(settings);
  renderer.beginFrame(camera);
  renderer.drawMesh(trianglePositions(0.0), oneTriangle(), albedo);
  const Image image = renderer.finishFrame();
  const double shade = 0.3 + 0.7 * 0.8;
  const Eigen::Vector3d centroid(0.0, (-0.6 - 0.6 + 0.8) / 3.0, 0.0);
  expectNear(pixelAt(image, camera, centroid), toRgba(albedo * shade), kByteTolerance, "centroid");
  EXPECT_EQ(image.pixel(1, 1), toRgba(settings.background));
  EXPECT_EQ(image.pixel(62, 62), toRgba(settings.background));
  EXPECT_EQ(pixelAt(image, camera, {0.0, 0.95, 0.0}), toRgba(settings.background));
}

TEST(Renderer, BackFacesAreLitWithTheFlippedNormalOnlyWhenTwoSided) {
  RenderSettings settings = smallSettings();
  const Camera camera = frontOrthographic();
  stain::Triangles reversed(1, 3);
  reversed << 0, 2, 1;
  const Color albedo(0.5, 0.6, 0.7);
  const Eigen::Vector3d centroid(0.0, -0.1333, 0.0);
  const Image twoSided = renderMesh(trianglePositions(0.0), reversed,
                                    Eigen::MatrixX3d(albedo.transpose().replicate(3, 1)), camera,
                                    settings);
  expectNear(pixelAt(twoSided, camera, centroid), toRgba(albedo * (0.3 + 0.7 * 0.8)),
             kByteTolerance, "two-sided back face");
  settings.twoSidedLighting = false;
  const Image oneSided = renderMesh(trianglePositions(0.0), reversed,
                                    Eigen::MatrixX3d(albedo.transpose().replicate(3, 1)), camera,
                                    settings);
  expectNear(pixelAt(oneSided, camera, centroid), toRgba(albedo * 0.3), kByteTolerance,
             "one-sided back face: ambient only");
}

TEST(Renderer, NearerTriangleWinsInEitherDrawOrder) {
  for (Projection projection : {Projection::Orthographic, Projection::Perspective}) {
    Camera camera = frontOrthographic();
    camera.projection = projection;
    RenderSettings settings = smallSettings();
    settings.lightDirection = {0.0, 0.0, 1.0};
    settings.ambient = 0.0;
    settings.diffuse = 1.0;
    const Color far(1.0, 0.0, 0.0), near(0.0, 1.0, 0.0);
    for (bool nearFirst : {true, false}) {
      Renderer renderer(settings);
      renderer.beginFrame(camera);
      if (nearFirst) renderer.drawMesh(trianglePositions(0.5), oneTriangle(), near);
      renderer.drawMesh(trianglePositions(0.0), oneTriangle(), far);
      if (!nearFirst) renderer.drawMesh(trianglePositions(0.5), oneTriangle(), near);
      const Image image = renderer.finishFrame();
      const Rgba8 center = pixelAt(image, camera, {0.0, -0.1, 0.5});
      EXPECT_EQ(center, (Rgba8{0, 255, 0, 255}))
          << "projection " << static_cast<int>(projection) << " nearFirst " << nearFirst;
    }
  }
}

// A flat n x n grid of quads in z = 0 over [-1, 1]^2, two triangles per quad.
void gridMesh(int n, stain::RowVectors3& positions, stain::Triangles& faces) {
  positions.resize((n + 1) * (n + 1), 3);
  for (int j = 0; j <= n; ++j) {
    for (int i = 0; i <= n; ++i) {
      // Irregular spacing so edges hit sample centres in many ways.
      const double u = -1.0 + 2.0 * i / n + (i % n != 0 ? 0.013 * std::sin(7.0 * i + j) : 0.0);
      const double v = -1.0 + 2.0 * j / n + (j % n != 0 ? 0.011 * std::cos(5.0 * j + i) : 0.0);
      positions.row(j * (n + 1) + i) << u, v, 0.0;
    }
  }
  faces.resize(2 * n * n, 3);
  int f = 0;
  for (int j = 0; j < n; ++j) {
    for (int i = 0; i < n; ++i) {
      const int a = j * (n + 1) + i, b = a + 1, c = a + n + 1, d = c + 1;
      faces.row(f++) << a, b, d;
      faces.row(f++) << a, d, c;
    }
  }
}

TEST(Renderer, SharedEdgesLeaveNoCracksWithoutSupersampling) {
  stain::RowVectors3 positions;
  stain::Triangles faces;
  gridMesh(23, positions, faces);
  RenderSettings settings;
  settings.width = 173;
  settings.height = 173;
  settings.supersampling = 1;
  settings.background = {0.0, 0.0, 0.0};
  settings.ambient = 1.0;
  settings.diffuse = 0.0;
  for (Projection projection : {Projection::Orthographic, Projection::Perspective}) {
    Camera camera = frontOrthographic();
    camera.projection = projection;
    camera.orthographicHeight = 2.2;
    camera.verticalFovDegrees = 2.0 * std::atan(1.1 / 5.0) * 180.0 / kPi;
    const Image image = renderMesh(positions, faces,
                                   Eigen::MatrixX3d::Ones(positions.rows(), 3), camera, settings);
    int holes = 0;
    int covered = 0;
    for (int y = 0; y < image.height(); ++y) {
      for (int x = 0; x < image.width(); ++x) {
        // Pixel centres well inside the square [-1, 1]^2 must be covered.
        const double worldX = (x + 0.5 - 86.5) * 2.2 / 173.0;
        const double worldY = (86.5 - y - 0.5) * 2.2 / 173.0;
        if (std::abs(worldX) > 0.97 || std::abs(worldY) > 0.97) continue;
        ++covered;
        if (image.pixel(x, y).r != 255) ++holes;
      }
    }
    EXPECT_GT(covered, 20000);
    EXPECT_EQ(holes, 0) << "projection " << static_cast<int>(projection);
  }
}

TEST(Renderer, EdgesThroughSampleCentresAreCoveredOnce) {
  // A regular grid whose vertices sit exactly on pixel centres: every
  // horizontal, vertical and diagonal edge passes through sample centres, so
  // only the tie rule (top-left) decides who covers them.
  const int n = 16;
  stain::RowVectors3 positions((n + 1) * (n + 1), 3);
  const double halfPixel = 1.0 / 64.0;  // 64 pixels over 2 metres
  for (int j = 0; j <= n; ++j) {
    for (int i = 0; i <= n; ++i) {
      positions.row(j * (n + 1) + i) << -0.75 + 1.5 * i / n + halfPixel,
          -0.75 + 1.5 * j / n - halfPixel, 0.0;
    }
  }
  stain::Triangles faces(2 * n * n, 3);
  for (int j = 0, f = 0; j < n; ++j) {
    for (int i = 0; i < n; ++i) {
      const int a = j * (n + 1) + i, b = a + 1, c = a + n + 1, d = c + 1;
      faces.row(f++) << a, b, d;
      faces.row(f++) << a, d, c;
    }
  }
  RenderSettings settings = smallSettings();
  settings.supersampling = 1;
  settings.background = {0.0, 0.0, 0.0};
  settings.ambient = 1.0;
  settings.diffuse = 0.0;
  const Image image = renderMesh(positions, faces, Eigen::MatrixX3d::Ones(positions.rows(), 3),
                                 frontOrthographic(), settings);
  // The grid spans pixel centres 8.5 .. 56.5 on both axes. Its left and top
  // boundary edges are top-left edges (samples on them are in), its right and
  // bottom ones are not (out): covered pixels are exactly 8..55.
  int holes = 0;
  for (int y = 8; y <= 55; ++y) {
    for (int x = 8; x <= 55; ++x) holes += image.pixel(x, y).r == 255 ? 0 : 1;
  }
  EXPECT_EQ(holes, 0);
  for (int k = 8; k <= 56; ++k) {
    EXPECT_EQ(image.pixel(56, k).r, 0) << k;
    EXPECT_EQ(image.pixel(k, 56).r, 0) << k;
  }
}

TEST(Renderer, EdgeCoverageIsAntialiasedBySupersampling) {
  // A square whose left edge lies on the boundary between the two sample
  // columns of pixel 32 (2x2 supersampling): that pixel is half covered.
  RenderSettings settings = smallSettings();
  settings.background = {0.0, 0.0, 0.0};
  settings.ambient = 1.0;
  settings.diffuse = 0.0;
  const Camera camera = frontOrthographic();  // 64 pixels across 2 metres
  const double edgeX = (32.5 - 32.0) * 2.0 / 64.0;
  stain::RowVectors3 positions(4, 3);
  positions << edgeX, -0.5, 0.0, 0.9, -0.5, 0.0, 0.9, 0.5, 0.0, edgeX, 0.5, 0.0;
  stain::Triangles faces(2, 3);
  faces << 0, 1, 2, 0, 2, 3;
  const Image image = renderMesh(positions, faces, Eigen::MatrixX3d::Ones(4, 3), camera, settings);
  EXPECT_EQ(image.pixel(31, 32).r, 0);
  // Half the samples: linear 0.5, averaged before the sRGB encoding (188, not 128).
  EXPECT_NEAR(image.pixel(32, 32).r, linearToSrgbByte(0.5), kByteTolerance);
  EXPECT_EQ(image.pixel(33, 32).r, 255);
}

TEST(Renderer, ColoursAreInterpolatedPerspectiveCorrectly) {
  // A long strip receding from the camera, colour linear in world depth z.
  // With one sample per pixel, each pixel shows the colour where the ray
  // through its centre hits the strip; screen-linear interpolation would be
  // off by up to a third of the colour range here.
  const double floorY = -0.3, length = 20.0;
  stain::RowVectors3 positions(4, 3);
  positions << -0.2, floorY, 0.0, 0.2, floorY, 0.0, 0.2, floorY, -length, -0.2, floorY, -length;
  stain::Triangles faces(2, 3);
  faces << 0, 1, 2, 0, 2, 3;
  Eigen::MatrixX3d colors(4, 3);
  colors << 1, 0, 0, 1, 0, 0, 0, 0, 1, 0, 0, 1;
  Camera camera;
  camera.eye = {0.0, 0.0, 1.0};
  camera.target = {0.0, floorY, -3.0};
  camera.verticalFovDegrees = 60.0;
  RenderSettings settings = smallSettings();
  settings.width = 200;
  settings.height = 200;
  settings.supersampling = 1;
  settings.ambient = 1.0;
  settings.diffuse = 0.0;
  const Image image = renderMesh(positions, faces, colors, camera, settings);
  const Eigen::Vector3d forward = (camera.target - camera.eye).normalized();
  const Eigen::Vector3d right = forward.cross(camera.up).normalized();
  const Eigen::Vector3d up = right.cross(forward);
  const double scale = 0.5 * settings.height / std::tan(camera.verticalFovDegrees * kPi / 360.0);
  int checked = 0;
  double worstScreenLinearError = 0.0;
  for (int y = 0; y < settings.height; ++y) {
    const int x = settings.width / 2;
    const Eigen::Vector3d ray = forward + right * ((x + 0.5 - 100.0) / scale) -
                                up * ((y + 0.5 - 100.0) / scale);
    if (ray.y() >= 0.0) continue;
    const double t = (floorY - camera.eye.y()) / ray.y();
    const double z = camera.eye.z() + t * ray.z();
    if (z > -0.05 || z < -length + 0.05) continue;
    const double blue = -z / length;
    const Rgba8 expected = toRgba(Color(1.0 - blue, 0.0, blue));
    expectNear(image.pixel(x, y), expected, kByteTolerance, "row " + std::to_string(y));
    ++checked;
    // What screen-linear interpolation between the strip's screen ends gives.
    const double yNear = projectToImage(camera, 200, 200, {0.0, floorY, 0.0}).y();
    const double yFar = projectToImage(camera, 200, 200, {0.0, floorY, -length}).y();
    const double linear = (y + 0.5 - yNear) / (yFar - yNear);
    worstScreenLinearError = std::max(worstScreenLinearError, std::abs(linear - blue));
  }
  EXPECT_GT(checked, 40);
  EXPECT_GT(worstScreenLinearError, 0.3);  // the check above is a discriminating one
}

TEST(Renderer, GeometryBehindTheCameraIsClipped) {
  // A large floor y = 0 seen from just above it, extending behind the eye.
  stain::RowVectors3 positions(4, 3);
  positions << -50, 0, 50, 50, 0, 50, 50, 0, -50, -50, 0, -50;
  stain::Triangles faces(2, 3);
  faces << 0, 1, 2, 0, 2, 3;
  Camera camera;
  camera.eye = {0.0, 1.0, 0.0};
  camera.target = {0.0, 1.0, -1.0};
  camera.verticalFovDegrees = 90.0;
  camera.nearDistance = 0.05;
  RenderSettings settings = smallSettings();
  settings.ambient = 1.0;
  settings.diffuse = 0.0;
  const Image image =
      renderMesh(positions, faces, Eigen::MatrixX3d::Constant(4, 3, 0.5), camera, settings);
  const Rgba8 floor = toRgba(Color::Constant(0.5));
  EXPECT_EQ(image.pixel(32, 60), floor);                        // below the horizon
  EXPECT_EQ(image.pixel(32, 4), toRgba(settings.background));   // sky
  EXPECT_EQ(image.pixel(2, 62), floor);                         // floor reaches the corner
}

TEST(Renderer, WireframeMarksEdgesOnly) {
  RenderSettings settings = smallSettings();
  settings.width = 128;
  settings.height = 128;
  const Camera camera = frontOrthographic();
  SurfaceStyle style;
  style.wireframe = true;
  // The wire is drawn inside each triangle up to half the width from an edge
  // (a shared edge gets the full width from its two triangles).
  style.wireframeWidth = 4.0;
  style.wireframeColor = {0.0, 0.0, 0.0};
  const Color albedo(1.0, 1.0, 1.0);
  Renderer renderer(settings);
  renderer.beginFrame(camera);
  renderer.drawMesh(trianglePositions(0.0), oneTriangle(), albedo, style);
  const Image image = renderer.finishFrame();
  const Rgba8 black{0, 0, 0, 255};
  // One pixel inside each edge's midpoint: the whole pixel lies within the
  // 2-pixel band, so it is pure wire colour.
  const double pixel = 2.0 / 128.0;
  EXPECT_EQ(pixelAt(image, camera, {0.0, -0.6 + pixel, 0.0}), black);
  const Eigen::Vector3d rightMid(0.4, 0.1, 0.0), leftMid(-0.4, 0.1, 0.0);
  const Eigen::Vector3d inwardRight = Eigen::Vector3d(-1.4, -0.8, 0.0).normalized();
  const Eigen::Vector3d inwardLeft(-inwardRight.x(), inwardRight.y(), 0.0);
  EXPECT_EQ(pixelAt(image, camera, rightMid + pixel * inwardRight), black);
  EXPECT_EQ(pixelAt(image, camera, leftMid + pixel * inwardLeft), black);
  // Three pixels inside: past the band.
  EXPECT_NE(pixelAt(image, camera, rightMid + 3.0 * pixel * inwardRight), black);
  expectNear(pixelAt(image, camera, {0.0, -0.1333, 0.0}), toRgba(albedo * (0.3 + 0.7 * 0.8)),
             kByteTolerance, "interior stays shaded");
}

TEST(Renderer, WireframeOfAClippedTriangleDoesNotDrawTheClipEdge) {
  // The floor of the clipping test with wireframe: the near-plane cut would
  // be a horizontal line at the bottom of the image if it were drawn.
  stain::RowVectors3 positions(3, 3);
  positions << -50, 0, 50, 50, 0, 50, 0, 0, -50;
  Camera camera;
  camera.eye = {0.0, 1.0, 0.0};
  camera.target = {0.0, 1.0, -1.0};
  camera.verticalFovDegrees = 90.0;
  camera.nearDistance = 0.5;
  RenderSettings settings = smallSettings();
  settings.ambient = 1.0;
  settings.diffuse = 0.0;
  SurfaceStyle style;
  style.wireframe = true;
  style.wireframeWidth = 3.0;
  style.wireframeColor = {0.0, 0.0, 0.0};
  Renderer renderer(settings);
  renderer.beginFrame(camera);
  renderer.drawMesh(positions, oneTriangle(), Color(1.0, 1.0, 1.0), style);
  const Image image = renderer.finishFrame();
  for (int x = 20; x < 44; ++x) EXPECT_EQ(image.pixel(x, 63).r, 255) << x;
}

TEST(Renderer, PolylinesRespectDepthUnlessToldOtherwise) {
  const RenderSettings settings = smallSettings();
  const Camera camera = frontOrthographic();
  stain::RowVectors3 line(3, 3);
  line << -0.9, -0.2, -1.0, 0.0, -0.2, -1.0, 0.9, -0.2, -1.0;  // behind the triangle
  LineStyle style;
  style.color = {1.0, 1.0, 0.0};
  style.width = 3.0;
  const Rgba8 yellow{255, 255, 0, 255};
  for (bool depthTest : {true, false}) {
    style.depthTest = depthTest;
    Renderer renderer(settings);
    renderer.beginFrame(camera);
    renderer.drawMesh(trianglePositions(0.0), oneTriangle(), Color(0.5, 0.5, 0.5));
    renderer.drawPolyline(line, style);
    const Image image = renderer.finishFrame();
    EXPECT_EQ(pixelAt(image, camera, {0.0, -0.2, -1.0}) == yellow, !depthTest) << depthTest;
    EXPECT_EQ(pixelAt(image, camera, {-0.85, -0.2, -1.0}), yellow);  // outside the triangle
  }
  // A depth bias lifts a path lying exactly on a surface above it.
  style.depthTest = true;
  style.depthBias = 1e-3;
  line.col(2).setZero();
  Renderer renderer(settings);
  renderer.beginFrame(camera);
  renderer.drawMesh(trianglePositions(0.0), oneTriangle(), Color(0.5, 0.5, 0.5));
  renderer.drawPolyline(line, style);
  EXPECT_EQ(pixelAt(renderer.finishFrame(), camera, {0.1, -0.2, 0.0}), yellow);
}

TEST(Renderer, PointsAreDiscsOfTheGivenDiameter) {
  RenderSettings settings = smallSettings();
  settings.supersampling = 1;
  const Camera camera = frontOrthographic();
  stain::RowVectors3 points(1, 3);
  points << 0.0, 0.0, 0.0;  // projects to pixel corner (32, 32)
  LineStyle style;
  style.color = {1.0, 1.0, 1.0};
  style.width = 6.0;  // radius 3 pixels
  Renderer renderer(settings);
  renderer.beginFrame(camera);
  renderer.drawPoints(points, style);
  const Image image = renderer.finishFrame();
  int lit = 0;
  for (int y = 0; y < 64; ++y) {
    for (int x = 0; x < 64; ++x) {
      const bool inside = std::hypot(x + 0.5 - 32.0, y + 0.5 - 32.0) <= 3.0;
      EXPECT_EQ(image.pixel(x, y).r == 255, inside) << x << "," << y;
      lit += inside ? 1 : 0;
    }
  }
  EXPECT_EQ(lit, 32);  // pixel centres within radius 3 of a pixel corner
}

TEST(Renderer, FramingFitsTheBoxTightly) {
  const Eigen::AlignedBox3d box(Eigen::Vector3d(-1.0, 0.0, 2.0), Eigen::Vector3d(3.0, 0.5, 2.8));
  const int width = 300, height = 200;
  const double margin = 1.1;
  for (Projection projection : {Projection::Perspective, Projection::Orthographic}) {
    for (const Eigen::Vector3d& view :
         {Eigen::Vector3d(0, 0, -1), Eigen::Vector3d(1, -0.5, 0.3), Eigen::Vector3d(0, -1, 0)}) {
      const Camera camera = frameBoundingBox(box, view, double(width) / height, projection,
                                             Eigen::Vector3d::UnitY(), 40.0, margin);
      double extent = 0.0;
      for (int corner = 0; corner < 8; ++corner) {
        const Eigen::Vector3d p = projectToImage(
            camera, width, height, box.corner(static_cast<Eigen::AlignedBox3d::CornerType>(corner)));
        EXPECT_GT(p.z(), 0.0);
        extent = std::max({extent, std::abs(p.x() - 0.5 * width) / (0.5 * width),
                           std::abs(p.y() - 0.5 * height) / (0.5 * height)});
      }
      EXPECT_NEAR(extent, 1.0 / margin, 1e-9) << "view " << view.transpose();
      EXPECT_NEAR((camera.target - camera.eye).normalized().dot(view.normalized()), 1.0, 1e-12);
    }
  }
}

TEST(Renderer, FramingPointsFitsThePointsTightly) {
  // Points on a tilted ring: its bounding box is much larger than its outline
  // from most directions, so framing the points must be tighter than the box.
  stain::RowVectors3 points(64, 3);
  for (int k = 0; k < 64; ++k) {
    const double a = 2.0 * kPi * k / 64.0;
    points.row(k) << std::cos(a), 0.6 * std::sin(a), 0.8 * std::sin(a);
  }
  const int width = 200, height = 160;
  const double margin = 1.05;
  for (Projection projection : {Projection::Perspective, Projection::Orthographic}) {
    const Eigen::Vector3d view(0.2, -0.3, -1.0);
    const Camera camera = framePoints(points, view, double(width) / height, projection,
                                      Eigen::Vector3d::UnitY(), 35.0, margin);
    double extent = 0.0;
    for (int k = 0; k < 64; ++k) {
      const Eigen::Vector3d p = projectToImage(camera, width, height, points.row(k).transpose());
      extent = std::max({extent, std::abs(p.x() - 0.5 * width) / (0.5 * width),
                         std::abs(p.y() - 0.5 * height) / (0.5 * height)});
    }
    EXPECT_NEAR(extent, 1.0 / margin, 1e-9) << static_cast<int>(projection);
  }
}

TEST(Renderer, OutputIsDeterministicAndBuffersAreReusable) {
  stain::RowVectors3 positions;
  stain::Triangles faces;
  gridMesh(9, positions, faces);
  positions.col(2) = (positions.col(0).array() * 3.0).sin() * 0.3;
  Eigen::MatrixX3d colors(positions.rows(), 3);
  for (Eigen::Index i = 0; i < positions.rows(); ++i) {
    colors.row(i) << 0.5 + 0.5 * positions(i, 0), 0.5, 0.5 - 0.5 * positions(i, 1);
  }
  const Camera camera = frameBoundingBox(boundingBox(positions), {-0.3, -0.4, -1.0}, 4.0 / 3.0);
  RenderSettings settings = smallSettings();
  settings.supersampling = 3;
  SurfaceStyle style;
  style.wireframe = true;
  Renderer renderer(settings);
  renderer.beginFrame(camera);
  renderer.drawMesh(positions, faces, colors, style);
  const Image first = renderer.finishFrame();
  renderer.beginFrame(camera);
  renderer.drawMesh(positions, faces, colors, style);
  EXPECT_TRUE(renderer.finishFrame() == first);
  EXPECT_TRUE(renderMesh(positions, faces, colors, camera, settings, style) == first);
}

TEST(Renderer, NonFiniteColoursShowMagenta) {
  RenderSettings settings = smallSettings();
  settings.ambient = 1.0;
  settings.diffuse = 0.0;
  const Camera camera = frontOrthographic();
  Eigen::MatrixX3d colors = Eigen::MatrixX3d::Constant(3, 3, 0.5);
  colors(1, 2) = std::nan("");
  const Image image = renderMesh(trianglePositions(0.0), oneTriangle(), colors, camera, settings);
  // Only vertex 1 is bad: its corner is magenta, the opposite corner grey.
  // Near the bad corner the colour is nearly (1, 0, 1); the sRGB encoding
  // lifts the little grey left in green (linear 0.03 -> byte ~48).
  expectNear(pixelAt(image, camera, {0.75, -0.58, 0.0}), Rgba8{245, 24, 245, 255}, 30, "bad corner");
  expectNear(pixelAt(image, camera, {0.0, 0.75, 0.0}), toRgba(Color::Constant(0.5)), 10, "good corner");
}

TEST(Renderer, RejectsBadInput) {
  RenderSettings settings;
  settings.supersampling = 5;
  EXPECT_THROW(Renderer{settings}, std::invalid_argument);
  settings.supersampling = 2;
  settings.width = 0;
  EXPECT_THROW(Renderer{settings}, std::invalid_argument);
  Renderer renderer{RenderSettings{}};
  EXPECT_THROW(renderer.drawMesh(trianglePositions(0.0), oneTriangle(), Color(1, 1, 1)),
               std::logic_error);
  renderer.beginFrame(frontOrthographic());
  stain::Triangles bad(1, 3);
  bad << 0, 1, 3;
  EXPECT_THROW(renderer.drawMesh(trianglePositions(0.0), bad, Color(1, 1, 1)),
               std::invalid_argument);
  EXPECT_THROW(renderer.drawMesh(trianglePositions(0.0), oneTriangle(), Eigen::MatrixX3d(2, 3)),
               std::invalid_argument);
  Camera degenerate;
  degenerate.target = degenerate.eye;
  EXPECT_THROW(renderer.beginFrame(degenerate), std::invalid_argument);
}

}  // namespace
}  // namespace blot::engine
