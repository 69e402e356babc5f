// Stage and term names, and the report of which terms ran. The step records
// bits and counts only (no allocation in the frame loop); strings are made
// here, on demand, outside it.
#include <blot/stain/step_profile.h>

#include <cmath>
#include <sstream>
#include <string>

namespace blot::stain {
namespace {

constexpr const char* kStageNames[] = {
    "guard",    "drops",           "cloth",    "geometry",       "sources", "liquid-band", "forces",  "film-pressure",
    "film-friction", "advect-velocity", "coriolis", "advect-density", "diffuse", "interact", "validate",    "coupling"};
// Every output names stages through stageName (and stageKey, made from it).
static_assert(sizeof(kStageNames) / sizeof(kStageNames[0]) == kStageCount, "one name per Stage, in Stage order");

}  // namespace

const char* stageName(Stage stage) {
  const int k = static_cast<int>(stage);
  return k >= 0 && k < kStageCount ? kStageNames[k] : "unknown";
}

std::string stageKey(Stage stage) {
  std::string key = stageName(stage);
  for (char& c : key)
    if (c == '-') c = '_';
  return key;
}

bool parseStage(const std::string& name, Stage& stage) {
  for (int k = 0; k < kStageCount; ++k)
    if (name == kStageNames[k]) {
      stage = static_cast<Stage>(k);
      return true;
    }
  return false;
}

Stage stageOf(StepTerm term) {
  switch (term) {
    case StepTerm::RotationFits:
    case StepTerm::RigidFrames:
    case StepTerm::IntrinsicRebuild:
    case StepTerm::SystemAssembly: return Stage::Geometry;
    case StepTerm::Gravity:
    case StepTerm::LinearInertia: return Stage::BodyForces;
    case StepTerm::Coriolis: return Stage::Coriolis;
    case StepTerm::FilmPressure: return Stage::FilmPressure;
    case StepTerm::FilmFriction: return Stage::FilmFriction;
    case StepTerm::VelocityAdvection: return Stage::AdvectVelocity;
    case StepTerm::DensityAdvection: return Stage::AdvectDensity;
    case StepTerm::DensityDiffusionKrylov:
    case StepTerm::DensityDiffusionDirect:
    case StepTerm::VelocityDiffusionKrylov:
    case StepTerm::VelocityDiffusionDirect:
    case StepTerm::Factorization:
    case StepTerm::SoluteWithSolvent:
    case StepTerm::VelocityDiffusionByMass: return Stage::Diffuse;
    case StepTerm::Absorption:
    case StepTerm::Adsorption:
    case StepTerm::Evaporation: return Stage::Interact;
    case StepTerm::Sources: return Stage::Sources;
  }
  return Stage::Guard;
}

double StepProfile::stainTime() const {
  double sum = 0;
  for (int k = static_cast<int>(kFirstStainStage); k <= static_cast<int>(kLastStainStage); ++k)
    sum += milliseconds[static_cast<size_t>(k)];
  return sum;
}

StepReport checkTimeStep(double h) {
  StepReport report;
  report.stage = Stage::Guard;
  if (!(h > 0) || !std::isfinite(h)) {
    report.status = StepStatus::InvalidArgument;
    report.message = "time step must be finite and positive, got " + std::to_string(h);
  }
  return report;
}

const char* stepTermName(StepTerm term) {
  switch (term) {
    case StepTerm::RotationFits: return "rotation-fits";
    case StepTerm::RigidFrames: return "rigid-frames";
    case StepTerm::IntrinsicRebuild: return "intrinsic-rebuild";
    case StepTerm::Factorization: return "factorization";
    case StepTerm::Gravity: return "gravity";
    case StepTerm::LinearInertia: return "linear-inertia";
    case StepTerm::Coriolis: return "coriolis";
    case StepTerm::FilmPressure: return "film-pressure";
    case StepTerm::FilmFriction: return "film-friction";
    case StepTerm::VelocityAdvection: return "velocity-advection";
    case StepTerm::DensityAdvection: return "density-advection";
    case StepTerm::DensityDiffusionKrylov: return "density-diffusion-krylov";
    case StepTerm::DensityDiffusionDirect: return "density-diffusion-direct";
    case StepTerm::VelocityDiffusionKrylov: return "velocity-diffusion-krylov";
    case StepTerm::VelocityDiffusionDirect: return "velocity-diffusion-direct";
    case StepTerm::Absorption: return "absorption";
    case StepTerm::Adsorption: return "adsorption";
    case StepTerm::Evaporation: return "evaporation";
    case StepTerm::Sources: return "sources";
    case StepTerm::SystemAssembly: return "system-assembly";
    case StepTerm::SoluteWithSolvent: return "solute-with-solvent";
    case StepTerm::VelocityDiffusionByMass: return "velocity-diffusion-by-mass";
  }
  return "unknown";
}

std::string describeTerms(const StepProfile& profile) {
  std::ostringstream out;
  bool any = false;
  for (int k = 0; k < kStepTermCount; ++k) {
    const auto term = static_cast<StepTerm>(1u << k);
    if (!profile.ran(term)) continue;
    out << (any ? " " : "") << stepTermName(term);
    any = true;
    switch (term) {
      case StepTerm::RotationFits:
      case StepTerm::RigidFrames:
        out << '[' << profile.geometryVertices << ']';
        break;
      case StepTerm::DensityAdvection:
        out << '[' << profile.advectionVertices << ']';
        break;
      case StepTerm::DensityDiffusionKrylov:
      case StepTerm::DensityDiffusionDirect:
        out << '[' << profile.densityDiffusionVertices << ']';
        break;
      case StepTerm::VelocityDiffusionKrylov:
      case StepTerm::VelocityDiffusionDirect:
        out << '[' << profile.velocityDiffusionVertices << ']';
        break;
      default:
        break;
    }
  }
  if (!any) out << "none";
  out << " (wet " << profile.wetVertices << " + halo " << profile.haloVertices;
  if (profile.soakedVertices > 0) out << ", soaked " << profile.soakedVertices;
  out << " of " << profile.vertexCount << ")";
  return out.str();
}

}  // namespace blot::stain
