// Stages "film-pressure" and "film-friction": the liquid as a thin viscous
// film (film_flow.h; docs/transport.md, "The liquid film").
//
// Design note. The film's depth-averaged momentum at lubrication order is
//   du/dt = −∇φ − k u (+ inertia, Coriolis, advection),  φ = −g·x + g_n H,
//   k = 3ν/(H(H + 3λ)),
// with φ the variation of the potential energy Σ A(−σ g·x + ½ρ g_n H²) with
// the mass, so the force and the energy the budget audits are one. Gravity
// and pressure are one discrete gradient: written apart (tangential gravity
// per vertex plus −g_n∇H) they do not cancel on a curved mesh, and a lake at
// rest in a bowl starts to slosh. The gradient at a vertex is the area-
// weighted mean of its faces' P1 gradients of φ*, written as differences
// from φ_i so that equal potentials give exactly zero. At the shoreline a dry
// neighbour's φ* is min(−g·x_j, φ_i): the hydrostatic reconstruction of
// Audusse et al. (2004), which keeps the dry bank above a lake from pushing
// the lake (the pressure there is the lake's own) while a dry slope below
// the film drains it. Rejected: the paper's pointwise tangential gravity plus
// a separate −g_n∇H (not balanced), and g_n = |g·n| (the film would be pressed
// onto the cloth from both sides).
//
// The drag is integrated by backward Euler, u⁺ = u/(1 + hk): exact decay
// for a uniform film, dissipative for any h, and the steady state is exactly
// the Nusselt value a/k. Where hk ≫ 1 the film is friction-dominated and its
// thickness follows the lubrication equation ∂H/∂t = ∇·(D∇H) with
// D = g_n H²(H + 3λ)/(3ν); an explicit step of it needs h D/ℓ² ≤ 1/4, and
// where friction is weak the film is shallow water, whose explicit step needs
// h √(g_n H)/ℓ ≤ 1/2. One criterion covers both, (h/n)² g_n H /
// (ℓ² (1 + hk/n)) ≤ 1/4, and the solver sub-steps potential, friction and
// density advection (filmSubsteps) n times where the step is too long.
#include <blot/stain/stages/film_flow.h>

#include <algorithm>
#include <cmath>
#include <limits>

#include <blot/stain/stages/liquid_band.h>

#include "numerics/threads.h"

namespace blot::stain {
namespace {

// Below this many vertices the potential's loop runs on one thread (as the
// body forces': a few dozen flops a vertex do not pay for the fork/join).
constexpr int kMinParallelVertices = 8192;

/// The effective gravity g − p̈_i acting on the film at vertex i (m/s²).
Vector3 effectiveGravity(const StepContext& ctx, const ExtrinsicGeometry& geometry, int i) {
  Vector3 g = ctx.switches.gravity ? ctx.gravity : Vector3::Zero();
  if (ctx.switches.linearInertia && geometry.vertexAccelerations.rows() == geometry.positions.rows())
    g -= geometry.vertexAccelerations.row(i).transpose();
  return g;
}

/// g_n = max(0, −(g − p̈)·n) at vertex i (m/s²): side convention in film_flow.h.
double normalGravity(const StepContext& ctx, const ExtrinsicGeometry& geometry, int i) {
  const Vector3 normal = geometry.frames[static_cast<size_t>(i)].col(2);
  return std::max(0.0, -effectiveGravity(ctx, geometry, i).dot(normal));
}

/// −g·x_i (m²/s²): the film's gravitational potential at vertex i.
double heightPotential(const StepContext& ctx, const ExtrinsicGeometry& geometry, int i) {
  if (!ctx.switches.gravity) return 0.0;
  return -ctx.gravity.dot(geometry.positions.row(i).transpose());
}

}  // namespace

double filmDragRate(double thickness, const LiquidParameters& liquid) {
  const double denominator = thickness * (thickness + 3.0 * liquid.slipLength);
  if (!(denominator > 0.0)) return std::numeric_limits<double>::infinity();
  return 3.0 * liquid.kinematicViscosity / denominator;
}

bool isFilmVertex(const StainState& state, const std::vector<char>& wet, int i) {
  return wet[static_cast<size_t>(i)] == LiquidBand::kHoldsLiquid && state.solvent[i] + state.solute[i] > 0.0;
}

void FilmScratch::resize(int vertexCount) {
  accelerations = ComplexVector::Zero(vertexCount);
  heads = Vector::Zero(vertexCount);
}

double filmAccelerations(const StepContext& ctx, const SurfaceTopology& topology, const ExtrinsicGeometry& geometry,
                         const StainState& state, const std::vector<char>& wet, const std::vector<int>& vertices,
                         FilmScratch& scratch) {
  const Triangles& faces = topology.faces();
  const std::vector<int>& offsets = topology.ringOffsets();
  const std::vector<int>& ringFaces = topology.ringFaces();
  const std::vector<signed char>& ringCorners = topology.ringCorners();
  const RowVectors3& p = geometry.positions;
  const int count = static_cast<int>(vertices.size());
  ComplexVector& accelerations = scratch.accelerations;
  Vector& heads = scratch.heads;
  // g_n H of every film vertex once (each is read from up to six faces).
  threads::runLoop(count >= kMinParallelVertices, [&] {
#pragma omp for schedule(static)
    for (int v = 0; v < count; ++v) {
      const int i = vertices[static_cast<size_t>(v)];
      if (isFilmVertex(state, wet, i)) heads[i] = normalGravity(ctx, geometry, i) * filmThickness(state, i, ctx.liquid);
    }
  });
  double largest = 0.0;
  threads::runLoop(count >= kMinParallelVertices, [&] {
    double mine = 0.0;  // this thread's largest |a| (max: the same in any order)
#pragma omp for schedule(static)
    for (int v = 0; v < count; ++v) {
      const int i = vertices[static_cast<size_t>(v)];
      if (!isFilmVertex(state, wet, i)) {
        accelerations[i] = Complex(0.0, 0.0);
        continue;
      }
      // φ*_j − φ_i for a corner j of one of i's faces (reconstructed at the
      // shoreline), with i's effective gravity g − p̈_i on the ring: the
      // surface's own acceleration is in the potential too, so a film on a
      // cloth accelerating rigidly is a film on a still one under g − p̈.
      const Vector3 g = effectiveGravity(ctx, geometry, i);
      const Vector3 xi = p.row(i).transpose();
      const double pressureI = heads[i];
      const auto difference = [&](int j) {
        const double height = -g.dot(p.row(j).transpose() - xi);
        if (!isFilmVertex(state, wet, j)) return std::min(height - pressureI, 0.0);
        return height + heads[j] - pressureI;
      };
      Vector3 weightedGradient = Vector3::Zero();  // Σ_T A_T ∇φ*_T (m³/s²)
      double area = 0.0;
      for (int m = offsets[static_cast<size_t>(i)]; m < offsets[static_cast<size_t>(i) + 1]; ++m) {
        const int f = ringFaces[static_cast<size_t>(m)];
        if (f < 0) continue;
        const int corner = ringCorners[static_cast<size_t>(m)];
        const int j = faces(f, (corner + 1) % 3), k = faces(f, (corner + 2) % 3);
        const Vector3 pi = p.row(i).transpose(), pj = p.row(j).transpose(), pk = p.row(k).transpose();
        const Vector3 doubleAreaNormal = (pj - pi).cross(pk - pi);  // 2 A_T N_T
        const double doubleArea = doubleAreaNormal.norm();
        if (!(doubleArea > 0.0)) continue;
        const Vector3 unitNormal = doubleAreaNormal / doubleArea;
        // A_T ∇λ_j = ½ N × (p_i − p_k), A_T ∇λ_k = ½ N × (p_j − p_i).
        weightedGradient += 0.5 * unitNormal.cross(difference(j) * (pi - pk) + difference(k) * (pj - pi));
        area += 0.5 * doubleArea;
      }
      if (!(area > 0.0)) {
        accelerations[i] = Complex(0.0, 0.0);
        continue;
      }
      const Vector3 a = -weightedGradient / area;
      const Matrix3& frame = geometry.frames[static_cast<size_t>(i)];
      accelerations[i] = Complex(frame.col(0).dot(a), frame.col(1).dot(a));
      mine = std::max(mine, std::abs(accelerations[i]));
    }
#pragma omp critical(blot_threads_combine)
    largest = std::max(largest, mine);
  });
  return largest;
}

void applyFilmPotential(const StepContext& ctx, const FilmScratch& scratch, const std::vector<char>& wet,
                        const std::vector<int>& vertices, StainState& state) {
  const double h = ctx.h;
  for (const int i : vertices)
    if (isFilmVertex(state, wet, i)) state.velocities[i] += h * scratch.accelerations[i];
}

double applyFilmFriction(const StepContext& ctx, const Vector& areas, const std::vector<char>& wet,
                         const std::vector<int>& vertices, StainState& state) {
  const double h = ctx.h;
  double dissipated = 0.0;
  for (const int i : vertices) {
    if (!isFilmVertex(state, wet, i)) continue;
    Complex& u = state.velocities[i];
    if (u == Complex(0.0, 0.0)) continue;
    const double k = filmDragRate(filmThickness(state, i, ctx.liquid), ctx.liquid);
    const double before = std::norm(u);
    u = std::isfinite(k) ? u / (1.0 + h * k) : Complex(0.0, 0.0);
    dissipated += 0.5 * areas[i] * (state.solvent[i] + state.solute[i]) * (before - std::norm(u));
  }
  return dissipated;
}

int filmSubsteps(const StepContext& ctx, const ExtrinsicGeometry& geometry, const StainState& state,
                 const LiquidBand& band, int cap) {
  if (!ctx.switches.filmPressure) return 1;
  const double h = ctx.h;
  double needed = 1.0;
  for (int w = 0; w < band.wetCount(); ++w) {  // the wet set: the film vertices are among them
    const int i = band.vertices[static_cast<size_t>(w)];
    if (!isFilmVertex(state, band.wetMask, i)) continue;
    const double H = filmThickness(state, i, ctx.liquid);
    const double waveSpeedSquared = normalGravity(ctx, geometry, i) * H;  // c² = g_n H (m²/s²)
    const double edge = band.distances[static_cast<size_t>(i)].shortestEdge;  // ℓ (m, intrinsic)
    if (!(waveSpeedSquared > 0.0) || !(edge > 0.0)) continue;
    // n sub-steps of h/n are stable where (h/n)² c² / (ℓ² (1 + hk/n)) ≤ 1/4:
    // n² + n hk − 4X ≥ 0 with X = h² c²/ℓ², hk = 0 without friction.
    const double X = h * h * waveSpeedSquared / (edge * edge);
    const double k = ctx.switches.filmFriction ? filmDragRate(H, ctx.liquid) : 0.0;
    if (!std::isfinite(k)) continue;  // no film to move
    const double Y = h * k;
    needed = std::max(needed, 0.5 * (std::sqrt(Y * Y + 16.0 * X) - Y));
  }
  const double steps = std::ceil(needed - 1e-12);
  return steps >= cap ? cap : std::max(1, static_cast<int>(steps));
}

FilmEnergy filmEnergy(const StepContext& ctx, const ExtrinsicGeometry& geometry, const Vector& areas,
                      const StainState& state, const std::vector<char>& wet) {
  FilmEnergy e;
  const int n = state.vertexCount();
  const bool withPressure = wet.size() == static_cast<size_t>(n) && geometry.frames.size() == static_cast<size_t>(n);
  for (int i = 0; i < n; ++i) {
    const double sigma = state.solvent[i] + state.solute[i];
    if (!(sigma > 0.0)) continue;
    const double a = areas[i];
    e.kinetic += 0.5 * a * sigma * std::norm(state.velocities[i]);
    if (ctx.switches.gravity) e.gravitational += a * sigma * heightPotential(ctx, geometry, i);
    if (withPressure && isFilmVertex(state, wet, i)) {
      const double H = filmThickness(state, i, ctx.liquid);
      e.pressure += 0.5 * a * ctx.liquid.liquidDensity * normalGravity(ctx, geometry, i) * H * H;
    }
  }
  return e;
}

FilmEnergy liquidEnergy(const Vector3& gravity, double liquidDensity, const SurfaceTopology& topology,
                        const RowVectors3& positions, const Vector& areas, const StainState& state) {
  FilmEnergy e;
  const Triangles& faces = topology.faces();
  const std::vector<int>& offsets = topology.ringOffsets();
  const std::vector<int>& ringFaces = topology.ringFaces();
  for (int i = 0; i < state.vertexCount(); ++i) {
    const double sigma = state.solvent[i] + state.solute[i];
    if (!(sigma > 0.0)) continue;
    const double a = areas[i];
    e.kinetic += 0.5 * a * sigma * std::norm(state.velocities[i]);
    e.gravitational += -a * sigma * gravity.dot(positions.row(i).transpose());
    Vector3 normal = Vector3::Zero();  // Σ_T 2 A_T N_T
    for (int m = offsets[static_cast<size_t>(i)]; m < offsets[static_cast<size_t>(i) + 1]; ++m) {
      const int f = ringFaces[static_cast<size_t>(m)];
      if (f < 0) continue;
      const Vector3 pa = positions.row(faces(f, 0)).transpose();
      normal += (positions.row(faces(f, 1)).transpose() - pa).cross(positions.row(faces(f, 2)).transpose() - pa);
    }
    const double length = normal.norm();
    if (!(length > 0.0)) continue;
    const double gn = std::max(0.0, -gravity.dot(normal / length));
    const double H = sigma / liquidDensity;
    e.pressure += 0.5 * a * liquidDensity * gn * H * H;
  }
  return e;
}

}  // namespace blot::stain
