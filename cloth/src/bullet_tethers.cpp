// Tethers: each vertex's nearest pin at its rest geodesic distance (fast
// marching), and BulletCloth::enforceTethers, which holds nodes within it.
#include "bullet_cloth_impl.h"

#include <algorithm>
#include <cmath>
#include <functional>
#include <limits>
#include <queue>
#include <utility>
#include <vector>

namespace blot::cloth::detail {

namespace {

// Tethers (long-range attachments): every vertex the pins can reach is tied to
// its nearest pin, at its rest geodesic distance computed by fast marching
// (Kimmel–Sethian: Dijkstra's order, but a vertex whose triangle has both
// other corners done gets the planar wavefront's arrival time, falling back
// to edge paths where the wave does not cross the triangle). Rejected: plain
// Dijkstra over edges, which overestimates distances on a grid by up to 8%,
// and the tether hands that out as stretch. O(#V log #V).
double wavefrontArrival(const Eigen::Vector3d& ea, const Eigen::Vector3d& eb, double ta, double tb) {
  // Solve |∇T| = 1 for the linear T on the triangle (v, v + ea, v + eb) with
  // T(v + ea) = ta, T(v + eb) = tb: with E = [ea eb], Q = (EᵀE)⁻¹, λ = Q(t − T1),
  // λᵀ(EᵀE)λ = 1, i.e. (1ᵀQ1)T² − 2(1ᵀQt)T + tᵀQt − 1 = 0, larger root.
  Eigen::Matrix2d gram;
  gram << ea.dot(ea), ea.dot(eb), ea.dot(eb), eb.dot(eb);
  const double det = gram.determinant();
  if (!(det > 1e-12 * gram(0, 0) * gram(1, 1))) return std::numeric_limits<double>::infinity();
  const Eigen::Matrix2d q = gram.inverse();
  const Eigen::Vector2d t(ta, tb), one(1, 1);
  const double qa = one.dot(q * one), qb = one.dot(q * t), qc = t.dot(q * t) - 1;
  const double disc = qb * qb - qa * qc;
  if (disc < 0) return std::numeric_limits<double>::infinity();
  const double arrival = (qb + std::sqrt(disc)) / qa;
  // Causal only if the wave arrives from inside the triangle: −∇T in the cone
  // of ea, eb, i.e. λ ≤ 0 componentwise.
  const Eigen::Vector2d lambda = q * (t - arrival * one);
  if (arrival < std::max(ta, tb) || lambda.maxCoeff() > 1e-12 * arrival) return std::numeric_limits<double>::infinity();
  return arrival;
}

// Vertex-to-face incidence in CSR form (faces of vertex i are
// faceOf[offsets[i] .. offsets[i+1]), in face order).
void vertexFaces(const Eigen::MatrixX3i& faces, int n, std::vector<int>& offsets, std::vector<int>& faceOf) {
  offsets.assign(static_cast<size_t>(n) + 1, 0);
  for (Eigen::Index f = 0; f < faces.rows(); ++f)
    for (int k = 0; k < 3; ++k) ++offsets[static_cast<size_t>(faces(f, k)) + 1];
  for (int i = 0; i < n; ++i) offsets[static_cast<size_t>(i) + 1] += offsets[static_cast<size_t>(i)];
  faceOf.assign(static_cast<size_t>(offsets.back()), -1);
  std::vector<int> fill(offsets.begin(), offsets.end() - 1);
  for (Eigen::Index f = 0; f < faces.rows(); ++f)
    for (int k = 0; k < 3; ++k) faceOf[static_cast<size_t>(fill[static_cast<size_t>(faces(f, k))]++)] = static_cast<int>(f);
}

}  // namespace

void nearestPins(const Eigen::MatrixX3i& faces, const Eigen::MatrixX3d& rest, const std::vector<ClothPin>& pins,
                 std::vector<int>& pinOf, Eigen::VectorXd& distance) {
  const int n = static_cast<int>(rest.rows());
  std::vector<int> offsets, faceOf;
  vertexFaces(faces, n, offsets, faceOf);
  pinOf.assign(static_cast<size_t>(n), -1);
  distance = Eigen::VectorXd::Constant(n, std::numeric_limits<double>::infinity());
  std::vector<char> done(static_cast<size_t>(n), 0);
  using Entry = std::pair<double, int>;  // ties resolved by vertex index: deterministic
  std::priority_queue<Entry, std::vector<Entry>, std::greater<Entry>> heap;
  auto relax = [&](int v, double d, int pin) {
    if (d < distance[v]) {
      distance[v] = d;
      pinOf[static_cast<size_t>(v)] = pin;
      heap.emplace(d, v);
    }
  };
  for (size_t p = 0; p < pins.size(); ++p) relax(pins[p].vertex, 0.0, static_cast<int>(p));
  while (!heap.empty()) {
    const auto [d, u] = heap.top();
    heap.pop();
    if (done[static_cast<size_t>(u)] || d > distance[u]) continue;
    done[static_cast<size_t>(u)] = 1;
    const int pin = pinOf[static_cast<size_t>(u)];
    for (int k = offsets[static_cast<size_t>(u)]; k < offsets[static_cast<size_t>(u) + 1]; ++k) {
      const int f = faceOf[static_cast<size_t>(k)];
      // The face's other two corners: each is reached along its edge from u,
      // and, when the other one is done with the same pin, by the wavefront.
      const int c = faces(f, 0) == u ? 0 : faces(f, 1) == u ? 1 : 2;
      for (int side = 1; side <= 2; ++side) {
        const int target = faces(f, (c + side) % 3), other = faces(f, (c + 3 - side) % 3);
        if (done[static_cast<size_t>(target)]) continue;
        relax(target, d + (rest.row(target) - rest.row(u)).norm(), pin);
        if (!done[static_cast<size_t>(other)] || pinOf[static_cast<size_t>(other)] != pin) continue;
        const Eigen::Vector3d origin = rest.row(target);
        relax(target, wavefrontArrival(rest.row(u).transpose() - origin, rest.row(other).transpose() - origin, d, distance[other]), pin);
      }
    }
  }
}

}  // namespace blot::cloth::detail

namespace blot::cloth {

// Pulls each free node back onto the sphere of radius (tether length) around
// its pin's current position when it is outside, and gives it the matching
// velocity change Δx / hₛ (Bullet's own velocity update is (x − x_prev)/hₛ).
void BulletCloth::enforceTethers(double substep) {
  btSoftBody& body = *bullet_->body;
  const btScalar inverseStep = static_cast<btScalar>(1 / substep);
  for (int i = 0; i < vertexCount(); ++i) {
    const int p = tetherPin_[static_cast<size_t>(i)];
    if (p < 0 || released_[static_cast<size_t>(p)] || isPinned(i)) continue;
    btSoftBody::Node& node = body.m_nodes[i];
    const btVector3 offset = node.m_x - body.m_nodes[def_.pins[static_cast<size_t>(p)].vertex].m_x;
    const btScalar length = offset.length();
    const btScalar limit = static_cast<btScalar>(tetherLengths_[i]);
    if (length <= limit) continue;
    const btVector3 correction = offset * (limit / length - 1);
    node.m_x += correction;
    node.m_v += correction * inverseStep;
  }
}

}  // namespace blot::cloth
