// Which terms of the stain step ran, as text (issue 7: "each scene reports
// which terms ran").
//
// Design note. The step records the terms in StepProfile::terms, one bit per
// StepTerm, and the vertex counts in plain ints: no allocation in the frame
// loop, and a profile can be copied, summed and OR-ed by the engine. Only this
// report, made on demand outside the loop, builds a string. Vertex counts are
// printed beside the terms whose work is not simply "wet + halo": geometry on
// #V, density advection on its sub-step halo, diffusion on its Krylov support
// or the whole mesh. Rejected: a std::vector<std::string> of term names filled
// by the step (an allocation per step, which DESIGN.md rules out).
#include <blot/stain/step_context.h>

#include <sstream>

namespace blot::stain {

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
  out << " (wet " << profile.wetVertices << " + halo " << profile.haloVertices << " of " << profile.vertexCount
      << ")";
  return out.str();
}

}  // namespace blot::stain
