// Fabric layout: weft fields (constant on flat patches, smooth and tangent on
// curved ones, constraints met exactly), three patches meeting at a corner,
// the per-face output as consumed by anisotropicStiffness, and bad layouts
// rejected with a message naming the patch and face.
#include <blot/stain/fabric/fabric_layout.h>

#include <blot/stain/geometry/extrinsic_geometry.h>
#include <blot/stain/geometry/mesh_primitives.h>
#include <blot/stain/geometry/operators.h>

#include <gtest/gtest.h>

#include <cmath>
#include <string>
#include <vector>

#include "mesh_fixture.h"

namespace blot::stain {
namespace {

constexpr double kPi = 3.14159265358979323846;

struct Sheet {
  TriangleMesh mesh;
  SurfaceTopology topology;
  explicit Sheet(TriangleMesh m)
      : mesh(std::move(m)), topology(mesh.faces, static_cast<int>(mesh.vertexPositions.rows()), "sheet") {}
  const RowVectors3& positions() const { return mesh.vertexPositions; }
};

std::vector<int> allFaces(int count) {
  std::vector<int> faces(static_cast<size_t>(count));
  for (int f = 0; f < count; ++f) faces[static_cast<size_t>(f)] = f;
  return faces;
}

void expectLayoutError(const std::function<void()>& call, const std::vector<std::string>& fragments) {
  try {
    call();
    ADD_FAILURE() << "bad layout accepted";
  } catch (const FabricLayoutError& e) {
    for (const std::string& fragment : fragments)
      EXPECT_NE(std::string(e.what()).find(fragment), std::string::npos) << "missing '" << fragment << "' in: " << e.what();
  }
}

TEST(FabricLayout, OneConstraintOnAFlatPatchGivesAConstantField) {
  // A regular and an irregular (jittered) flat sheet: transport is exact on a
  // flat mesh, so the constant field solves the vector Laplace equation.
  for (const TriangleMesh& mesh : {gridMesh(10, 7, 2.0, 1.4), blot::test::jitteredGridMesh(16, 16, 1.0, 1.0, 0.2, 7u)}) {
    const Sheet sheet(mesh);
    const int faceCount = sheet.topology.faceCount();
    // The direction's normal component (z) is dropped: the weft lies in the cloth.
    const RowVectors3 weft = patchWeftField(sheet.topology, sheet.positions(), allFaces(faceCount),
                                            {{faceCount / 3, Vector3(1.0, 2.0, 0.5)}}, "sheet");
    const Vector3 expected = Vector3(1.0, 2.0, 0.0).normalized();
    ASSERT_EQ(weft.rows(), faceCount);
    double worst = 0.0;
    for (int f = 0; f < faceCount; ++f) worst = std::max(worst, (weft.row(f).transpose() - expected).norm());
    EXPECT_LT(worst, 1e-12);
  }
}

TEST(FabricLayout, ConstraintsAreMetExactlyAndTheFieldStaysInPlane) {
  const Sheet sheet(gridMesh(20, 10, 2.0, 1.0));
  const int faceCount = sheet.topology.faceCount();
  const std::vector<WeftConstraint> constraints = {{0, Vector3(1.0, 0.0, 0.0)},
                                                   {faceCount - 1, Vector3(1.0, 1.0, 0.0)}};
  const RowVectors3 weft = patchWeftField(sheet.topology, sheet.positions(), allFaces(faceCount), constraints);
  EXPECT_LT((weft.row(0).transpose() - Vector3::UnitX()).norm(), 1e-12);
  EXPECT_LT((weft.row(faceCount - 1).transpose() - Vector3(1, 1, 0).normalized()).norm(), 1e-12);
  for (int f = 0; f < faceCount; ++f) {
    EXPECT_NEAR(weft.row(f).norm(), 1.0, 1e-12);
    EXPECT_NEAR(weft(f, 2), 0.0, 1e-12);
    // Harmonic interpolation of the angle stays between the two constraints.
    const double angle = std::atan2(weft(f, 1), weft(f, 0));
    EXPECT_GE(angle, -1e-9);
    EXPECT_LE(angle, kPi / 4 + 1e-9);
  }
}

TEST(FabricLayout, FieldOnACurvedPatchIsTangentUnitAndSmooth) {
  const Sheet sphere(icosphereMesh(3));
  const std::vector<int> cap = facesWhere(sphere.topology, sphere.positions(),
                                          [](const Vector3& c) { return c.z() > 0.2; });
  ASSERT_GT(cap.size(), 100u);
  const RowVectors3 normals = faceNormals(sphere.topology, sphere.positions());
  const RowVectors3 weft = patchWeftField(sphere.topology, sphere.positions(), cap, {{cap[0], Vector3::UnitX()}}, "cap");
  std::vector<int> position(static_cast<size_t>(sphere.topology.faceCount()), -1);
  for (size_t i = 0; i < cap.size(); ++i) {
    position[static_cast<size_t>(cap[i])] = static_cast<int>(i);
    EXPECT_NEAR(weft.row(static_cast<Eigen::Index>(i)).norm(), 1.0, 1e-12);
    EXPECT_NEAR(weft.row(static_cast<Eigen::Index>(i)).dot(normals.row(cap[i])), 0.0, 1e-12);
  }
  // Neighbouring faces: directions differ by little more than the dihedral
  // angle (~0.1 rad at level 3); a flipped or noisy field would show > 0.5.
  double worst = 0.0;
  const std::vector<int>& twins = sphere.topology.halfedgeTwins();
  for (int h = 0; h < sphere.topology.halfedgeCount(); ++h) {
    const int a = position[static_cast<size_t>(h / 3)];
    const int b = twins[static_cast<size_t>(h)] < 0 ? -1 : position[static_cast<size_t>(twins[static_cast<size_t>(h)] / 3)];
    if (a < 0 || b < 0) continue;
    worst = std::max(worst, std::acos(std::min(1.0, weft.row(a).dot(weft.row(b)))));
  }
  std::printf("weft field on a level-3 icosphere cap (%zu faces): largest angle between neighbours %.3f rad\n",
              cap.size(), worst);
  EXPECT_LT(worst, 0.25);
}

TEST(FabricLayout, ThreePatchesMeetingAtACorner) {
  // Unit sheet split at (0.5, 0.5): A bottom-left (plain), B bottom-right
  // (twill 2/1), C top (rib knit); the three share the corner vertex
  // (paper Fig. 11d: three patterns at a corner).
  const Sheet sheet(gridMesh(12, 12, 1.0, 1.0));
  const auto region = [&](auto rule) { return facesWhere(sheet.topology, sheet.positions(), rule); };
  std::vector<FabricPatch> patches(3);
  patches[0].name = "A";
  patches[0].faces = region([](const Vector3& c) { return c.x() < 0.5 && c.y() < 0.5; });
  patches[0].pattern = presetWeavePattern("plain");
  patches[0].weftConstraints = {{patches[0].faces.front(), Vector3(1.0, 0.0, 0.0)}};
  patches[1].name = "B";
  patches[1].faces = region([](const Vector3& c) { return c.x() > 0.5 && c.y() < 0.5; });
  patches[1].pattern = presetWeavePattern("twill-2-1");
  patches[1].weftConstraints = {{patches[1].faces.back(), Vector3(1.0, 1.0, 0.0)}};
  patches[2].name = "C";
  patches[2].faces = region([](const Vector3& c) { return c.y() > 0.5; });
  patches[2].pattern = presetWeavePattern("rib-knit");
  patches[2].weftConstraints = {{patches[2].faces[40], Vector3(-0.5, 1.0, 0.0)}};

  Homogenizer homogenizer;
  const FabricLayout layout = fabricLayout(sheet.topology, sheet.positions(), patches, homogenizer);
  const std::vector<Vector3> expectedWeft = {Vector3::UnitX(), Vector3(1, 1, 0).normalized(),
                                             Vector3(-0.5, 1, 0).normalized()};
  const std::vector<Matrix2> expectedTensor = {homogenize(*patches[0].pattern).effective,
                                               homogenize(*patches[1].pattern).effective,
                                               homogenize(*patches[2].pattern).effective};
  for (int p = 0; p < 3; ++p) {
    SCOPED_TRACE(patches[static_cast<size_t>(p)].name);
    EXPECT_EQ(layout.patchTensors[static_cast<size_t>(p)], expectedTensor[static_cast<size_t>(p)]);
    for (int f : patches[static_cast<size_t>(p)].faces) {
      EXPECT_EQ(layout.facePatches[static_cast<size_t>(f)], p);
      EXPECT_LT((layout.faceWeftDirections.row(f).transpose() - expectedWeft[static_cast<size_t>(p)]).norm(), 1e-12);
      const Matrix2& s = expectedTensor[static_cast<size_t>(p)];
      EXPECT_EQ(layout.faceTensors.row(f), Eigen::RowVector3d(s(0, 0), s(0, 1), s(1, 1)));
    }
  }
  EXPECT_EQ(homogenizer.cacheMisses(), 3);
  fabricLayout(sheet.topology, sheet.positions(), patches, homogenizer);  // same patterns again
  EXPECT_EQ(homogenizer.cacheHits(), 3);
  EXPECT_EQ(homogenizer.cacheMisses(), 3);

  // As anisotropicStiffness reads it: for u = x, uᵀ L u = Σ_T A_T (S_T)_xx with
  // S_T = E S Eᵀ, E = [weft, n × weft]; patch areas 1/4, 1/4, 1/2.
  const SparseMatrix L = anisotropicStiffness(sheet.topology, sheet.positions(), layout.faceTensors,
                                              layout.faceWeftDirections);
  const Vector x = sheet.positions().col(0);
  double expected = 0.0;
  const double areas[3] = {0.25, 0.25, 0.5};
  for (int p = 0; p < 3; ++p) {
    const Vector3& e = expectedWeft[static_cast<size_t>(p)];
    Matrix2 basis;
    basis << e.x(), -e.y(), e.y(), e.x();  // weft, warp = +z × weft
    expected += areas[p] * (basis * expectedTensor[static_cast<size_t>(p)] * basis.transpose())(0, 0);
  }
  EXPECT_NEAR(x.dot(L * x), expected, 1e-10 * expected);
}

TEST(FabricLayout, DirectTensorPatchesAndSharedPatterns) {
  // Left half: a tensor given directly; right half: two label groups sharing
  // one pattern, homogenized once.
  TriangleMesh mesh = gridMesh(8, 4, 2.0, 1.0);
  const Sheet sheet(mesh);
  std::vector<int> labels(static_cast<size_t>(sheet.topology.faceCount()));
  const std::vector<int> left = facesWhere(sheet.topology, sheet.positions(), [](const Vector3& c) { return c.x() < 1.0; });
  const std::vector<int> top = facesWhere(sheet.topology, sheet.positions(), [](const Vector3& c) { return c.x() > 1.0 && c.y() > 0.5; });
  for (int f : top) labels[static_cast<size_t>(f)] = 1;
  for (int f : left) labels[static_cast<size_t>(f)] = 2;
  Matrix2 direct;
  direct << 4.0, 0.5, 0.5, 1.0;
  std::vector<FabricPatch> patches(3);
  patches[0].name = "direct";
  patches[0].faces = facesWithLabel(labels, 2);
  patches[0].tensor = direct;
  patches[0].weftConstraints = {{left[0], Vector3(0.0, -1.0, 0.0)}};
  for (int p = 1; p < 3; ++p) {
    patches[static_cast<size_t>(p)].name = "satin " + std::to_string(p);
    patches[static_cast<size_t>(p)].faces = facesWithLabel(labels, p - 1);
    patches[static_cast<size_t>(p)].pattern = presetWeavePattern("satin-5");
    patches[static_cast<size_t>(p)].weftConstraints = {{patches[static_cast<size_t>(p)].faces[0], Vector3::UnitX()}};
  }
  Homogenizer homogenizer;
  const FabricLayout layout = fabricLayout(sheet.topology, sheet.positions(), patches, homogenizer, 4);
  EXPECT_EQ(homogenizer.cacheMisses(), 1);
  EXPECT_EQ(homogenizer.cacheHits(), 1);
  for (int f : left) {
    EXPECT_EQ(layout.faceTensors.row(f), Eigen::RowVector3d(4.0, 0.5, 1.0));
    EXPECT_LT((layout.faceWeftDirections.row(f).transpose() + Vector3::UnitY()).norm(), 1e-12);
  }
  const Matrix2 satin = homogenize(presetWeavePattern("satin-5"), 4).effective;
  for (int f : top) EXPECT_EQ(layout.faceTensors.row(f), Eigen::RowVector3d(satin(0, 0), satin(0, 1), satin(1, 1)));
}

TEST(FabricLayout, PatchesFromFaceLabels) {
  const std::vector<int> labels = {2, 0, 2, 1, 0};
  EXPECT_EQ(facesWithLabel(labels, 2), (std::vector<int>{0, 2}));
  EXPECT_EQ(facesWithLabel(labels, 0), (std::vector<int>{1, 4}));
  EXPECT_TRUE(facesWithLabel(labels, 7).empty());
}

TEST(FabricLayout, RejectsBadLayoutsNamingPatchAndFace) {
  const Sheet sheet(gridMesh(6, 6, 1.0, 1.0));
  const int faceCount = sheet.topology.faceCount();
  const auto& topology = sheet.topology;
  const auto& positions = sheet.positions();
  Homogenizer homogenizer;
  const auto layoutOf = [&](std::vector<FabricPatch> patches) {
    return [&topology, &positions, &homogenizer, patches] { fabricLayout(topology, positions, patches, homogenizer); };
  };
  FabricPatch whole;
  whole.name = "whole";
  whole.faces = allFaces(faceCount);
  whole.weftConstraints = {{3, Vector3::UnitX()}};

  FabricPatch noConstraint = whole;
  noConstraint.weftConstraints.clear();
  expectLayoutError(layoutOf({noConstraint}), {"patch \"whole\"", "at least one weft constraint"});

  FabricPatch half = whole;
  half.faces.resize(static_cast<size_t>(faceCount / 2));
  expectLayoutError(layoutOf({half}), {"face " + std::to_string(faceCount / 2), "belongs to no fabric patch"});
  FabricPatch foreign = half;
  foreign.weftConstraints = {{faceCount - 1, Vector3::UnitX()}};
  expectLayoutError(layoutOf({foreign}), {"patch \"whole\"", "face " + std::to_string(faceCount - 1), "not part of the patch"});

  FabricPatch other = whole;
  other.name = "other";
  other.faces = {5};
  expectLayoutError(layoutOf({whole, other}), {"patch \"other\"", "face 5", "already belongs to patch \"whole\""});

  FabricPatch normal = whole;
  normal.weftConstraints = {{3, Vector3(0.0, 0.0, 2.0)}};
  expectLayoutError(layoutOf({normal}), {"patch \"whole\"", "weft_constraints[0]", "no component in the plane of face 3"});

  FabricPatch badTensor = whole;
  badTensor.tensor << 1.0, 2.0, 2.0, 1.0;
  expectLayoutError(layoutOf({badTensor}), {"patch \"whole\"", "symmetric positive definite"});

  // Two pieces that share no vertex, only one of them constrained.
  FabricPatch split = whole;
  split.faces = {0, 1, faceCount - 1};
  split.weftConstraints = {{0, Vector3::UnitX()}};
  FabricPatch rest = whole;
  rest.name = "rest";
  rest.faces.clear();
  for (int f = 2; f < faceCount - 1; ++f) rest.faces.push_back(f);
  expectLayoutError(layoutOf({split, rest}),
                    {"patch \"whole\"", "face " + std::to_string(faceCount - 1), "has no weft constraint"});

  // Opposite constraints on faces sharing vertices cancel there.
  FabricPatch opposite = whole;
  opposite.weftConstraints = {{0, Vector3::UnitX()}, {1, -Vector3::UnitX()}};
  expectLayoutError(layoutOf({opposite}), {"patch \"whole\"", "cancel"});
}

}  // namespace
}  // namespace blot::stain
