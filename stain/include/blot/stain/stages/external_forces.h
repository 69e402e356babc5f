#pragma once
/// Stages BodyForces and Coriolis (paper sec. 4): tangential gravity, linear
/// inertia −Fᵀp̈ and Coriolis −2ω×u, applied to the velocity on a mask (the
/// solver passes the liquid band: wet vertices and those with extended velocities).
#include <blot/stain/stain_state.h>
#include <blot/stain/step_context.h>
#include <blot/stain/geometry/surface_geometry.h>
#include <blot/stain/stages/velocity_advection.h>
#include <blot/stain/stages/vertex_visits.h>

namespace blot::stain {

/// Stage BodyForces: u_i += h · tangential part, in frame F_i^t, of (g − p̈_i),
/// each term as ctx.switches has it on (gravity, linearInertia). Forward Euler
/// is exact here: the forcing does not depend on u. With the film's pressure
/// on (and a `wet` mask) nothing: the film's potential carries both terms
/// (film_flow.h) and the rest of the band holds the liquid's extended u.
/// `wet` (#V, nonzero = worked on; the solver passes the liquid band)
/// restricts the work; pass an empty vector for all. `among` (optional): the
/// vertices visited instead of all #V, a superset of those `wet` marks
/// (visitCount; each vertex's update reads no other's, so the result is the
/// same bit for bit).
void applyBodyForces(const StepContext& ctx, const ExtrinsicGeometry& geometry, const std::vector<char>& wet,
                     StainState& state, const std::vector<int>* among = nullptr);

/// Stage BodyForces, first (ctx.switches.velocityOnFreeLiquid): u_i = 0 at
/// each vertex that `wet` marks LiquidBand::kHoldsLiquid (the wet set) but whose
/// free densities σ_f + σ_s are at most ctx.liquid.wetThreshold: liquid held in
/// the fibres only, which moves with the cloth. Nothing else resets such a
/// vertex's u (the band's extension overwrites dry vertices only), so the
/// forces kept accelerating it step after step (tens of m/s on a soaked
/// hanging flag), and that velocity set the step's Courant number, band reach
/// and backtrack lengths and the fluxes of liquid arriving there. `among` as
/// for applyBodyForces.
void clearVelocityWithoutFreeLiquid(const StepContext& ctx, const std::vector<char>& wet, StainState& state,
                                    const std::vector<int>* among = nullptr);

/// Turning angle π − γ of a boundary vertex's fan above which applyBoundaryWall
/// treats it as a corner (γ the fan's angle): 45°, a feature angle. Below it the
/// vertex is a bend of a smooth boundary sampled by the mesh.
inline constexpr double kWallCornerTurning = 0.25 * 3.14159265358979323846;

/// After the velocity's stages (ctx.switches.boundaryWall): the mesh boundary
/// is a wall, free slip and no penetration. The liquid has no flux across it
/// (the density advection's dual cells end there), so an outward u moves
/// nothing but keeps growing under the forces that press the liquid against
/// it (a hanging flag's hem), and then sets the step's Courant number, band
/// reach and backtrack lengths. At each boundary vertex that `wet` marks, with
/// its fan [0, γ] in the vertex's polar map (PolarMap::ringAngles: from the
/// first boundary edge, the frame's x axis, counter-clockwise to the last):
/// - a bend (π − kWallCornerTurning < γ < π): the outward part of u along the
///   fan's bisector is removed (u · n ≤ 0), so flow along the chord of the two
///   boundary neighbours, the discrete tangent of a curved rim, is kept;
/// - otherwise (a straight edge, a corner, a concave vertex): u becomes its
///   nearest point in the fan: unchanged inside; outside, its projection on
///   the nearer boundary edge's direction, or 0 where both projections point
///   off the mesh (a convex corner holds the liquid from both sides).
/// On a straight edge both rules remove the normal part. `among` as for
/// applyBodyForces. Returns how many vertices changed.
int applyBoundaryWall(const StepContext& ctx, const SurfaceTopology& topology, const IntrinsicGeometry& intrinsic,
                      const std::vector<char>& wet, StainState& state, const std::vector<int>* among = nullptr);

/// Stage Coriolis for a liquid that is not advected (or SplitRotation,
/// Explicit): with ω_n = ω_i·z (frame coordinates), ExactRotation and
/// SplitRotation multiply u_i by exp(−2iω_n h) (|u| preserved), Explicit adds
/// −2h ω_n (i u_i) (|u| grows by √(1 + 4ω_n²h²) each step; comparison only).
/// After a velocity advection with ExactRotation the solver uses
/// applyHalfFrameRotation and applyFrameVelocityChange instead. `wet` and
/// `among` as above (also for the two below).
void applyCoriolis(const StepContext& ctx, const ExtrinsicGeometry& geometry, const std::vector<char>& wet,
                   StainState& state, const std::vector<int>* among = nullptr);

/// applyBodyForces then applyCoriolis (the paper's whole force term, for tests
/// and callers without an advection between them).
void applyExternalForces(const StepContext& ctx, const ExtrinsicGeometry& geometry,
                         const std::vector<char>& wet, StainState& state);

/// The Coriolis term as a discrete frame change (docs/transport.md). The
/// solver keeps u between steps in the frame of the last step's midpoint,
/// F^{t−h/2} (where the relative velocity of a step, a chord, points along the
/// surface's tangent motion), and turns the frame increment exp(−iω_n h) in two
/// halves. applyHalfFrameRotation, first in the step: u_i ← exp(−iω_n h/2) u_i
/// (into F^t, before the inertia). applyFrameVelocityChange, after the
/// velocity advection: with v_k = (p_k^{t+h} − p_k^t)/h the frame velocity of
/// the step (m/s, world) and v(y) = Σ_c w_c v_{k_c} its value at the foot point
/// of i's backtrack (footVertices/footWeights, #V by 3, from advectVelocity),
///   u_i ← exp(−iω_n h/2) (u_i + tangential part in F_i^t of (v(y) − v_i)).
/// Together with the inertia −h p̈ the liquid's world velocity v + F u is
/// advected unchanged, so liquid at rest in an inertial frame stays at rest at
/// any ωh and no kinetic energy is created (tests/stain/coriolis_frame_test).
/// Only wet vertices (`wet` as above) are touched.
void applyHalfFrameRotation(const StepContext& ctx, const ExtrinsicGeometry& geometry, const std::vector<char>& wet,
                            StainState& state, const std::vector<int>* among = nullptr);
/// See applyHalfFrameRotation.
void applyFrameVelocityChange(const StepContext& ctx, const ExtrinsicGeometry& geometry,
                              const FootVertices& footVertices, const FootWeights& footWeights,
                              const std::vector<char>& wet, StainState& state,
                              const std::vector<int>* among = nullptr);

}  // namespace blot::stain
