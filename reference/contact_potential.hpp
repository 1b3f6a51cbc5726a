// Contact as a potential: the smooth log-barrier of incremental potential contact (IPC; Li et al.
// 2020, "Incremental Potential Contact", ACM TOG 39(4), sec. 4 and 5), its lagged, smoothed
// Coulomb friction, and the continuous collision check that bounds a step so that no gap ever
// reaches zero. Used by ref-be on scenes with contact (reference/ref_contact.hpp).
//
// The gaps d are those of core/contacts.hpp (eval_contact): a particle against a plane, a sphere
// (outside, inside, bowl) or another particle, in metres, radii included. For a gap d and the
// barrier distance d_hat > 0 (Li et al. 2020, eq. 6, on the unsquared gap):
//
//   b(d) = -(d - d_hat)^2 ln(d / d_hat)   for 0 < d < d_hat,   0 for d >= d_hat,   +inf for d <= 0
//
// b is C2 at d_hat and grows without bound as d -> 0+. The contact potential is
// B(x) = kappa sum_k b(d_k(x)) (J; kappa in J/m^2 = N/m): its force on a particle is
// -kappa b'(d) grad d, positive along the gap's gradient, the support of a resting particle.
//
// Friction (Li et al. 2020, sec. 5): for a contact k active at the start of the step (d < d_hat)
// the normal force lambda_k = -kappa b'(d_k) and the unit normal n_k are lagged (taken at the
// start of the step, x_n), and the tangential displacement over the step is
// u_k = P_k (dx_a - dx_b), P_k = I - n_k n_k^T, dx = x - x_n (the collider's own motion over the
// step subtracted for a moving sphere; dx_b = 0 for a fixed collider). Its potential is
//
//   D_k(x) = mu_k lambda_k f0(|u_k|),  f0'(y) = f1(y) = 2 (y / e) - (y / e)^2 for y < e, 1 else,
//   f0(y) = y^2 / e - y^3 / (3 e^2) + e / 3 for y < e, y else,   e = eps_v h,
//
// so -grad D_k is the Coulomb force mu lambda opposite to the sliding, smoothed to zero below a
// sliding speed |u| / h of eps_v (Li et al. 2020, eqs. 11 to 14).
//
// Surfaces (SurfaceBarrier below): with scene.surface_contact (between bodies) or
// scene.self_contact (within a body without tets), IPC's point-triangle and edge-edge pairs over
// Model::triangles and their edges (core/proximity.hpp for the distances and the collision
// check): the gap of a pair is its unsigned distance less its thickness (point-triangle: r_p +
// max r of the triangle, as core/surface_contact.hpp; edge-edge: max r of one edge + max r of
// the other), its barrier b(gap), an edge-edge pair's multiplied by the mollifier m (Li et al.
// 2020, eq. 23). The pairs considered follow core/surface_contact.hpp's rules: the points are
// the triangles' vertices; different bodies with scene.surface_contact; one body without tets
// with scene.self_contact, skipping a pair where a vertex of one primitive is a vertex of the
// other or shares a triangle with one; at least one of the four vertices dynamic.
#pragma once

#include <array>
#include <vector>

#include <Eigen/Core>

#include "core/bvh.hpp"
#include "core/contacts.hpp"
#include "core/model.hpp"
#include "core/proximity.hpp"

namespace pbdbench::barrier {

// b(d), b'(d), b''(d) for 0 < d (0 for d >= d_hat; b is +inf for d <= 0, b', b'' are then NaN).
double value(double d, double d_hat);
double first(double d, double d_hat);
double second(double d, double d_hat);

// The smoothed friction's f0 and f1 = f0' and f1' at y >= 0 for the threshold e = eps_v h > 0.
double f0(double y, double e);
double f1(double y, double e);
double f1_prime(double y, double e);

// A contact's gap with its first and second derivatives over the positions of its particles
// (a; and b for a particle pair): grad is 3 (one particle) or 6 entries, hess 3 x 3 or 6 x 6.
struct Gap {
  double d = 0.0;
  int size = 3;                     // 3 or 6
  Eigen::Matrix<double, 6, 1> grad = Eigen::Matrix<double, 6, 1>::Zero();
  Eigen::Matrix<double, 6, 6> hess = Eigen::Matrix<double, 6, 6>::Zero();
};

// The gap of `contact` at positions x and time t (moving spheres at their centre at t). Its value
// and gradient agree with eval_contact; the Hessian is that of the distance function: 0 for a
// plane, +-(I - n n^T) / |x - c| for a sphere (+ outside, - inside and bowl) and the same with
// the block pattern [[H, -H], [-H, H]] for a particle pair.
Gap gap(const Model& model, const Contact& contact, const Points& x, double t);

// The barrier's terms of a contact: its gap, except for a mesh collider, whose barrier is the sum
// over its triangles within d_hat of the particle of b(distance to the triangle - radius) (IPC's
// point-triangle pairs: smooth where the nearest triangle changes, as in a concave crease, where
// the distance to the mesh, a minimum over triangles, has a kink; a particle nearest to an edge
// or vertex shared by k triangles meets k equal terms there, as IPC's unmerged pairs do). Each
// term's Hessian is that of the distance to its triangle (0 in the face, the edge's or vertex's
// otherwise).
std::vector<Gap> barrier_terms(const Model& model, const Contact& contact, const Points& x,
                               double t, double d_hat);

// A lagged friction contact (see above): its particles, normal, lagged normal force, coefficient
// and the collider's displacement over the step (a moving sphere's surface point, else 0).
struct FrictionContact {
  Contact contact;
  Vec3 normal = Vec3::UnitY();       // unit, along grad d with respect to particle a
  double lambda = 0.0;               // N, lagged normal force
  double mu = 0.0;
  Vec3 collider_motion = Vec3::Zero();  // m, over the step (moving sphere)
};

// The tangential displacement u = P (dx_a - dx_b - collider_motion) of a friction contact at x
// against the start of the step x0 (dx_b only for a particle pair).
Vec3 tangential_displacement(const FrictionContact& f, const Points& x, const Points& x0);

// D(u) = mu lambda f0(|u|), its gradient and its Hessian with respect to u (3 and 3 x 3 in
// world coordinates, within the tangent plane); the Hessian is positive semi-definite.
double friction_value(const FrictionContact& f, const Vec3& u, double e);
Vec3 friction_gradient(const FrictionContact& f, const Vec3& u, double e);
Mat3 friction_hessian(const FrictionContact& f, const Vec3& u, double e);

// The largest alpha in [0, 1] such that along the straight paths x0 + s (x1 - x0), s in
// [0, alpha], no gap of the contacts in `candidates` falls below (1 - slack) of its value at s = 0
// (slack in (0, 1); Li et al. 2020, sec. 4.3, keep a fraction of the distance). The gaps are
// exact along the paths: linear in s for a plane; for a sphere and a particle pair, the
// distance between two linearly moving points (a moving sphere's centre taken linearly between
// t0 and t1) is the root of a quadratic. The paths of the candidates must start separated
// (d > 0). Every dynamic particle is checked against every plane and sphere whatever the
// candidates; particle pairs only where `candidates` lists them (the caller's broad phase).
double step_bound(const Model& model, const Points& x0, const Points& x1, double t0, double t1,
                  const std::vector<Contact>& pair_candidates, double slack);

// ---- Surfaces: point-triangle and edge-edge pairs ------------------------------------------

struct SurfacePair {
  proximity::PairKind kind = proximity::PairKind::PointTriangle;
  std::array<int, 4> v{};  // point-triangle: p, t0, t1, t2; edge-edge: a0, a1, b0, b1
  int first = -1, second = -1;  // point-triangle: vertex, triangle; edge-edge: edges (first < second)
  double thickness = 0.0;  // m
  double eps_x = 0.0;      // edge-edge: the mollifier's threshold (at rest)
};

// A pair's barrier term m b(gap) (m = 1 for point-triangle), with its gradient and Hessian over
// the 12 coordinates of its four vertices; gap = distance - thickness.
struct SurfaceTerm {
  double gap = 0.0;
  double value = 0.0;
  double b_first = 0.0;  // m b'(gap): minus the normal force per kappa (friction's lambda)
  proximity::Vec12 grad = proximity::Vec12::Zero();
  proximity::Mat12 hess = proximity::Mat12::Zero();
};

// A lagged friction pair: u = P sum_i c_i (x_i - x0_i), P = I - n n^T; c = (1, -u, -v, -w) with
// the closest point's barycentric coordinates (point-triangle), (1 - s, s, -(1 - t), -t) with the
// closest points' parameters (edge-edge); normal and lambda = -kappa m b'(gap) at the start.
struct SurfaceFriction {
  std::array<int, 4> v{};
  std::array<double, 4> c{};
  FrictionContact f;  // its normal, lambda and mu (its contact unused)
};

Vec3 tangential_displacement(const SurfaceFriction& f, const Points& x, const Points& x0);

class SurfaceBarrier {
 public:
  explicit SurfaceBarrier(const Model& model);
  bool enabled() const { return enabled_; }

  // The pairs with gap < margin at x (exact distances; a BVH of core/bvh.hpp over the triangles
  // and one over the edges as the broad phase), sorted: point-triangle by (vertex, triangle),
  // then edge-edge by (edge, edge).
  std::vector<SurfacePair> near(const Points& x, double margin) const;

  // Every pair that can come within margin of contact (gap < margin) somewhere on the straight
  // paths x0 -> x1: those whose primitives' boxes over the paths, grown by the pair's thickness
  // and margin, overlap (a superset).
  std::vector<SurfacePair> swept(const Points& x0, const Points& x1, double margin) const;

  static double gap(const SurfacePair& pair, const Points& x);
  static SurfaceTerm term(const SurfacePair& pair, const Points& x, double d_hat);
  // term's value alone (cheaper): m b(gap), +inf for gap <= 0.
  static double energy(const SurfacePair& pair, const Points& x, double d_hat);

  // The largest alpha in [0, limit] such that along x0 + s (x1 - x0), s in [0, alpha], every
  // pair's gap stays >= keep of its value at s = 0 (guaranteed; proximity::conservative_ccd per
  // pair of swept(x0, x1, d_hat); the pairs not swept stay farther than d_hat). Every such pair
  // must start with a gap > 0 (std::logic_error otherwise). `iterations` (when given) gets the
  // advances summed over the pairs.
  double step_bound(const Points& x0, const Points& x1, double d_hat, double keep, double limit,
                    long* iterations = nullptr) const;

  // The lagged friction pairs at x0 (gap < d_hat) for mu = Model::surface_friction > 0.
  std::vector<SurfaceFriction> lag_friction(const Points& x0, double kappa, double d_hat) const;

 private:
  bool point_triangle_allowed(int p, int t) const;
  bool edge_edge_allowed(int e, int f) const;
  SurfacePair make_point_triangle(int p, int t) const;
  SurfacePair make_edge_edge(int e, int f) const;
  template <class Visit>
  void candidates(const Points& x0, const Points* x1, double grow, Visit visit) const;

  const Model* model_ = nullptr;
  bool enabled_ = false;
  double max_radius_ = 0.0;
  std::vector<int> vertices_;                     // the triangles' vertices, sorted
  std::vector<std::array<int, 2>> edges_;         // the triangles' edges, sorted, v0 < v1
  std::vector<std::array<int, 3>> edge_as_triangle_;  // (v0, v1, v1): the edges' boxes
  std::vector<int> body_;
  std::vector<char> body_has_tets_;
  std::vector<std::vector<int>> neighbours_;      // self-contact: through the triangles, sorted
};

}  // namespace pbdbench::barrier
