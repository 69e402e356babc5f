// fitRotations, the batch rotation fit, as a free kernel of explicit inputs:
// a job's values do not depend on its batch (its lane, its companions, the
// padding of a batch that is not a multiple of the lanes), Newton agrees with
// the SVD, and the Svd method is rotationFromCovariance.
#include <blot/stain/geometry/rotation_fit.h>

#include <gtest/gtest.h>

#include <cmath>
#include <random>
#include <vector>

namespace blot::stain {
namespace {

/// A hexagonal one-ring per vertex, turned by a random rotation and sheared
/// by `noise`: the sums a fit reads (covariance, ring normal, reference edge)
/// and the rest frames.
struct Rings {
  std::vector<RotationFitJob> jobs;
  std::vector<Matrix3> restFrames;
  std::vector<Matrix3> rotations;
};

Rings makeRings(int count, double noise, unsigned seed) {
  std::mt19937 random(seed);
  std::normal_distribution<double> gauss(0.0, 1.0);
  Rings rings;
  for (int v = 0; v < count; ++v) {
    std::vector<Vector3> rest, current;
    for (int k = 0; k < 6; ++k) {
      const double angle = k * 3.14159265358979323846 / 3 + 0.1 * gauss(random);
      rest.emplace_back(std::cos(angle), std::sin(angle), 0.05 * gauss(random));
    }
    const Matrix3 R =
        Eigen::Quaterniond(gauss(random), gauss(random), gauss(random), gauss(random)).normalized().toRotationMatrix();
    Vector3 restNormal = Vector3::Zero();
    RotationFitJob job;
    job.vertex = v;
    job.covariance.setZero();
    job.normal.setZero();
    for (int k = 0; k < 6; ++k) {
      current.push_back(R * rest[static_cast<size_t>(k)] +
                        noise * Vector3(gauss(random), gauss(random), gauss(random)));
      job.covariance.noalias() += current.back() * rest[static_cast<size_t>(k)].transpose();
    }
    for (int k = 0; k < 6; ++k) {
      restNormal += rest[static_cast<size_t>(k)].cross(rest[static_cast<size_t>((k + 1) % 6)]);
      job.normal += current[static_cast<size_t>(k)].cross(current[static_cast<size_t>((k + 1) % 6)]);
    }
    job.normalSquared = job.normal.squaredNorm();
    job.edge = current[0];
    // F̄: z the rest normal, x the rest reference edge in the tangent plane.
    Matrix3 frame;
    frame.col(2) = restNormal.normalized();
    frame.col(1) = frame.col(2).cross(rest[0]).normalized();
    frame.col(0) = frame.col(1).cross(frame.col(2));
    rings.jobs.push_back(job);
    rings.restFrames.push_back(frame);
    rings.rotations.push_back(R);
  }
  return rings;
}

/// The fits' outputs, one slot per job, and the jobs pointed at them.
struct Outputs {
  std::vector<Eigen::Quaterniond> rotation;
  std::vector<Matrix3> frame, fit;
  RowVectors3 normals;
  explicit Outputs(int count)
      : rotation(static_cast<size_t>(count)), frame(static_cast<size_t>(count)), fit(static_cast<size_t>(count)),
        normals(RowVectors3::Zero(count, 3)) {}
  void point(std::vector<RotationFitJob>& jobs) {
    for (RotationFitJob& job : jobs) {
      const size_t k = static_cast<size_t>(job.vertex);
      job.rotation = &rotation[k];
      job.frame = &frame[k];
      job.fit = &fit[k];
      job.normals = &normals;
    }
  }
};

TEST(FitRotations, AJobsValuesDoNotDependOnItsBatch) {
  const int count = 7;  // one full batch of lanes, one with a padded lane
  Rings rings = makeRings(count, 0.02, 11);
  Outputs together(count), alone(count);
  together.point(rings.jobs);
  RotationFitStats togetherCounts;
  fitRotations(rings.jobs.data(), count, rings.restFrames, RotationFitMethod::WarmStartedNewton, togetherCounts);
  EXPECT_EQ(togetherCounts.fittedVertices, count);
  alone.point(rings.jobs);
  RotationFitStats aloneCounts;
  for (int k = count - 1; k >= 0; --k)
    fitRotations(&rings.jobs[static_cast<size_t>(k)], 1, rings.restFrames, RotationFitMethod::WarmStartedNewton,
                 aloneCounts);
  EXPECT_EQ(aloneCounts.fittedVertices, togetherCounts.fittedVertices);
  EXPECT_EQ(aloneCounts.newtonIterations, togetherCounts.newtonIterations);
  EXPECT_EQ(aloneCounts.svdFallbacks, togetherCounts.svdFallbacks);
  for (size_t k = 0; k < static_cast<size_t>(count); ++k) {
    EXPECT_EQ(together.rotation[k].coeffs(), alone.rotation[k].coeffs()) << "job " << k;
    EXPECT_EQ(together.frame[k], alone.frame[k]) << "job " << k;
    EXPECT_EQ(together.fit[k], alone.fit[k]) << "job " << k;
  }
  EXPECT_EQ(together.normals, alone.normals);
}

TEST(FitRotations, NewtonAgreesWithTheSvdAndTheSvdMethodIsRotationFromCovariance) {
  const int count = 9;
  Rings rings = makeRings(count, 0.05, 12);
  Outputs newton(count), svd(count);
  newton.point(rings.jobs);
  RotationFitStats newtonCounts, svdCounts;
  fitRotations(rings.jobs.data(), count, rings.restFrames, RotationFitMethod::WarmStartedNewton, newtonCounts);
  svd.point(rings.jobs);
  fitRotations(rings.jobs.data(), count, rings.restFrames, RotationFitMethod::Svd, svdCounts);
  EXPECT_EQ(svdCounts.fittedVertices, count);
  EXPECT_EQ(svdCounts.newtonIterations, 0);
  EXPECT_GT(newtonCounts.newtonIterations, 0);
  EXPECT_EQ(newtonCounts.svdFallbacks, 0);  // Newton decided every fit
  for (size_t k = 0; k < static_cast<size_t>(count); ++k) {
    const RotationFitJob& job = rings.jobs[k];
    const Matrix3 reference = rotationFromCovariance(job.covariance);
    EXPECT_EQ(svd.fit[k], reference) << "job " << k;
    EXPECT_LT((newton.fit[k] - reference).cwiseAbs().maxCoeff(), 1e-12) << "job " << k;
    // Near the rotation the ring was turned by (the shear moves it a little).
    EXPECT_LT((newton.fit[k] - rings.rotations[k]).cwiseAbs().maxCoeff(), 0.1) << "job " << k;
    EXPECT_LT((newton.frame[k] - newton.fit[k] * rings.restFrames[k]).cwiseAbs().maxCoeff(), 1e-14) << "job " << k;
    const Vector3 unit = job.normal.normalized();
    for (int c = 0; c < 3; ++c) EXPECT_NEAR(newton.normals(job.vertex, c), unit(c), 1e-15) << "job " << k;
  }
}

}  // namespace
}  // namespace blot::stain
