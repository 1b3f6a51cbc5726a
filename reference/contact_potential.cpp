// The IPC barrier, lagged friction and the continuous collision check. contact_potential.hpp.
#include "reference/contact_potential.hpp"

#include <algorithm>
#include <cmath>
#include <limits>
#include <stdexcept>

#include "core/surface_contact.hpp"

namespace pbdbench::barrier {

namespace {
constexpr double kNaN = std::numeric_limits<double>::quiet_NaN();
constexpr double kInf = std::numeric_limits<double>::infinity();
}  // namespace

double value(double d, double d_hat) {
  if (!(d > 0.0)) return kInf;
  if (d >= d_hat) return 0.0;
  const double s = d - d_hat;
  return -s * s * std::log(d / d_hat);
}

double first(double d, double d_hat) {
  if (!(d > 0.0)) return kNaN;
  if (d >= d_hat) return 0.0;
  const double s = d - d_hat;
  return -2.0 * s * std::log(d / d_hat) - s * s / d;
}

double second(double d, double d_hat) {
  if (!(d > 0.0)) return kNaN;
  if (d >= d_hat) return 0.0;
  const double s = d - d_hat;
  return -2.0 * std::log(d / d_hat) - 4.0 * s / d + s * s / (d * d);
}

double f0(double y, double e) {
  if (y >= e) return y;
  return y * y / e - y * y * y / (3.0 * e * e) + e / 3.0;
}

double f1(double y, double e) {
  if (y >= e) return 1.0;
  const double r = y / e;
  return 2.0 * r - r * r;
}

double f1_prime(double y, double e) {
  if (y >= e) return 0.0;
  return 2.0 / e - 2.0 * y / (e * e);
}

namespace {

// The unit up direction that decides a bowl's open half.
bool below_centre(const Model& model, const Vec3& x, const Vec3& c) {
  return (x - c).dot(up_direction(model)) < 0.0;
}

// Gap and derivatives of the distance |p| - R (sign +1) or R - |p| (sign -1) with respect to p.
void radial(const Vec3& p, double R, double sign, double& d, Vec3& g, Mat3& H) {
  const double r = p.norm();
  d = sign * (r - R);
  const Vec3 n = r > 0.0 ? Vec3(p / r) : Vec3(Vec3::UnitY());
  g = sign * n;
  H = r > 0.0 ? Mat3(sign * (Mat3::Identity() - n * n.transpose()) / r) : Mat3(Mat3::Zero());
}

}  // namespace

Gap gap(const Model& model, const Contact& c, const Points& x, double t) {
  Gap out;
  const Vec3 xa = x.row(c.a).transpose();
  const double ra = model.radius[static_cast<size_t>(c.a)];
  switch (c.kind) {
    case ContactKind::Plane: {
      const PlaneCollider& p = model.planes[static_cast<size_t>(c.b)];
      const double nn = p.normal.norm();
      out.d = (p.normal.dot(xa) + p.offset) / nn - ra;
      out.grad.head<3>() = p.normal / nn;
      break;
    }
    case ContactKind::Sphere: {
      const SphereCollider& s = model.spheres[static_cast<size_t>(c.b)];
      const Vec3 centre = sphere_center(model, s, t);
      double d;
      Vec3 g;
      Mat3 H;
      if (s.side == SphereSide::Outside)
        radial(xa - centre, s.radius + ra, 1.0, d, g, H);
      else
        radial(xa - centre, s.radius - ra, -1.0, d, g, H);
      out.d = d;
      out.grad.head<3>() = g;
      out.hess.topLeftCorner<3, 3>() = H;
      break;
    }
    case ContactKind::Mesh: {
      // The unsigned distance to the mesh (IPC's): every accepted state keeps it above the
      // radius, so the particle never changes sides and the signed distance is the same there.
      const MeshCollider& m = model.meshes[static_cast<size_t>(c.b)];
      const MeshDistance md = mesh_distance(m, xa - mesh_offset(model, m, t));
      out.d = md.unsigned_distance - ra;
      out.grad.head<3>() = md.direction;
      out.hess.topLeftCorner<3, 3>() = md.hessian;
      break;
    }
    case ContactKind::Particle: {
      const Vec3 xb = x.row(c.b).transpose();
      const double rb = model.radius[static_cast<size_t>(c.b)];
      double d;
      Vec3 g;
      Mat3 H;
      radial(xa - xb, ra + rb, 1.0, d, g, H);
      out.d = d;
      out.size = 6;
      out.grad.head<3>() = g;
      out.grad.tail<3>() = -g;
      out.hess.topLeftCorner<3, 3>() = H;
      out.hess.topRightCorner<3, 3>() = -H;
      out.hess.bottomLeftCorner<3, 3>() = -H;
      out.hess.bottomRightCorner<3, 3>() = H;
      break;
    }
    case ContactKind::Edge:      // ref-be takes surface contacts (vertex-triangle, edge-edge)
    case ContactKind::Triangle:  // as SurfaceBarrier pairs, never here
      throw std::logic_error("ref-be: a surface contact (vertex-triangle or edge-edge) reached the barrier");
  }
  return out;
}

std::vector<Gap> barrier_terms(const Model& model, const Contact& c, const Points& x, double t,
                               double d_hat) {
  if (c.kind != ContactKind::Mesh) return {gap(model, c, x, t)};
  std::vector<Gap> out;
  const MeshCollider& m = model.meshes[static_cast<size_t>(c.b)];
  const Vec3 p = x.row(c.a).transpose() - mesh_offset(model, m, t);
  const double r = model.radius[static_cast<size_t>(c.a)];
  TriangleBvh::Box box;
  box.grow(p);
  box.lo.array() -= r + d_hat;
  box.hi.array() += r + d_hat;
  std::vector<int> tris;
  m.bvh.overlapping(box, [&](int k) { tris.push_back(k); });
  std::sort(tris.begin(), tris.end());
  for (int k : tris) {
    const auto& tri = m.triangles[static_cast<size_t>(k)];
    Vec3 bary;
    const Vec3 a = m.vertices.row(tri[0]).transpose(), b = m.vertices.row(tri[1]).transpose(),
               cc = m.vertices.row(tri[2]).transpose();
    const Vec3 q = closest_point_on_triangle(p, a, b, cc, &bary);
    const Vec3 u = p - q;
    const double dist = u.norm();
    if (!(dist > 0.0)) {  // on the triangle: the barrier is infinite there
      Gap g;
      g.d = -r;
      out.push_back(g);
      continue;
    }
    if (!(dist - r < d_hat)) continue;
    Gap g;
    g.d = dist - r;
    const Vec3 dir = u / dist;
    g.grad.head<3>() = dir;
    int nonzero = 0, zero = 0;  // the closest feature: the regions give exact zeros
    for (int i = 0; i < 3; ++i) {
      if (bary[i] != 0.0) ++nonzero;
      else zero = i;
    }
    if (nonzero == 1) {
      g.hess.topLeftCorner<3, 3>() = (Mat3::Identity() - dir * dir.transpose()) / dist;
    } else if (nonzero == 2) {
      const int e0 = (zero + 1) % 3, e1 = (zero + 2) % 3;
      const Vec3 te = (m.vertices.row(tri[static_cast<size_t>(e1)]) - m.vertices.row(tri[static_cast<size_t>(e0)]))
                          .transpose()
                          .normalized();
      g.hess.topLeftCorner<3, 3>() =
          (Mat3::Identity() - te * te.transpose() - dir * dir.transpose()) / dist;
    }
    out.push_back(g);
  }
  return out;
}

Vec3 tangential_displacement(const FrictionContact& f, const Points& x, const Points& x0) {
  Vec3 dx = (x.row(f.contact.a) - x0.row(f.contact.a)).transpose() - f.collider_motion;
  if (f.contact.kind == ContactKind::Particle)
    dx -= (x.row(f.contact.b) - x0.row(f.contact.b)).transpose();
  return dx - f.normal * f.normal.dot(dx);
}

double friction_value(const FrictionContact& f, const Vec3& u, double e) {
  return f.mu * f.lambda * f0(u.norm(), e);
}

Vec3 friction_gradient(const FrictionContact& f, const Vec3& u, double e) {
  const double y = u.norm();
  if (y == 0.0) return Vec3::Zero();
  return f.mu * f.lambda * f1(y, e) * u / y;
}

Mat3 friction_hessian(const FrictionContact& f, const Vec3& u, double e) {
  const Mat3 P = Mat3::Identity() - f.normal * f.normal.transpose();
  const double y = u.norm();
  const double k = f.mu * f.lambda;
  if (y < 1e-12 * e) return k * (2.0 / e) * P;  // the limit y -> 0 of both terms below
  const Vec3 w = u / y;
  const Mat3 ww = w * w.transpose();
  return k * (f1_prime(y, e) * ww + (f1(y, e) / y) * (P - ww));
}

namespace {

// Smallest s in (0, 1] where |p + s q| crosses the radius `target` from the side it starts on
// (outside: decreasing to target; inside: increasing to target), or +inf when it does not.
double radial_crossing(const Vec3& p, const Vec3& q, double target, bool from_outside) {
  // |p + s q|^2 - target^2 = a s^2 + b s + c
  const double a = q.squaredNorm();
  const double b = 2.0 * p.dot(q);
  const double c = p.squaredNorm() - target * target;
  if (a == 0.0) return kInf;
  const double disc = b * b - 4.0 * a * c;
  if (from_outside) {
    if (disc < 0.0) return kInf;
    // The first root: where the distance first drops to target (c > 0 at s = 0).
    const double sq = std::sqrt(disc);
    const double s = (-b - sq) / (2.0 * a);
    return s >= 0.0 ? s : kInf;
  }
  // Inside (c < 0): the larger root is where it leaves the ball; disc > 0 always then.
  const double sq = std::sqrt(std::max(disc, 0.0));
  const double s = (-b + sq) / (2.0 * a);
  return s >= 0.0 ? s : kInf;
}

// The distance from the point y0 + s dy to triangle t of the mesh: convex in s.
double triangle_distance(const MeshCollider& m, int t, const Vec3& y0, const Vec3& dy, double s) {
  const auto& tri = m.triangles[static_cast<size_t>(t)];
  const Vec3 p = y0 + s * dy;
  const Vec3 q = closest_point_on_triangle(p, m.vertices.row(tri[0]).transpose(),
                                           m.vertices.row(tri[1]).transpose(),
                                           m.vertices.row(tri[2]).transpose());
  return (p - q).norm();
}

// The largest s in [0, limit] such that the distance from y0 + s' dy to triangle t stays above
// `target` for every s' in [0, s] (the distance at s = 0 is above it). The distance is convex in s
// (a point moving on a line, a convex set): its minimum on [0, limit] by golden-section search;
// when that minimum is below target, the crossing on the decreasing side by bisection, whose
// lower end (still above target) is returned. Both to 1e-12 of limit: the bound keeps the gap
// above target up to that fraction of the step, a small part of the 10 % it keeps.
double triangle_crossing(const MeshCollider& m, int t, const Vec3& y0, const Vec3& dy,
                         double target, double limit) {
  if (triangle_distance(m, t, y0, dy, limit) > target) {
    // The minimum may still lie inside; golden-section search for it.
    double lo = 0.0, hi = limit;
    const double phi = 0.5 * (std::sqrt(5.0) - 1.0);
    double a = hi - phi * (hi - lo), b = lo + phi * (hi - lo);
    double fa = triangle_distance(m, t, y0, dy, a), fb = triangle_distance(m, t, y0, dy, b);
    while (hi - lo > 1e-12 * limit) {
      if (fa <= target || fb <= target) break;
      if (fa < fb) {
        hi = b;
        b = a;
        fb = fa;
        a = hi - phi * (hi - lo);
        fa = triangle_distance(m, t, y0, dy, a);
      } else {
        lo = a;
        a = b;
        fa = fb;
        b = lo + phi * (hi - lo);
        fb = triangle_distance(m, t, y0, dy, b);
      }
    }
    if (fa > target && fb > target) return limit;
    limit = fa <= target ? a : b;
  }
  // f(0) > target >= f(limit): bisection keeps f(lo) > target >= f(hi).
  double lo = 0.0, hi = limit;
  while (hi - lo > 1e-12 * std::max(limit, 1e-300)) {
    const double mid = 0.5 * (lo + hi);
    if (triangle_distance(m, t, y0, dy, mid) > target) lo = mid;
    else hi = mid;
  }
  return lo;
}

// The step bound of particle path a0 -> a0 + da (radius r) against a mesh moving from offset o0
// to o1: in the mesh's frame the point moves on the straight path y0 + s dy.
double mesh_step_bound(const Model& model, const MeshCollider& m, const Vec3& a0, const Vec3& da,
                       double r, double t0, double t1, double keep, double alpha) {
  const Vec3 o0 = mesh_offset(model, m, t0), o1 = mesh_offset(model, m, t1);
  const Vec3 y0 = a0 - o0, dy = da - (o1 - o0);
  // The distance falls by at most |dy| over the path: from farther than r + |dy| / (1 - keep)
  // the gap keeps its fraction `keep` whatever the path does.
  const double reach = r + dy.norm() / (1.0 - keep);
  if (m.bvh.bounds().squared_distance(y0) > reach * reach) return alpha;
  const MeshDistance md = mesh_distance(m, y0, reach);
  if (md.triangle < 0) return alpha;
  const double d0 = md.unsigned_distance - r;
  if (d0 <= 0.0) return alpha;
  const double target = r + keep * d0;
  // Only triangles within target of some point of the path can be reached.
  TriangleBvh::Box path;
  path.grow(y0);
  path.grow(Vec3(y0 + dy));
  path.lo.array() -= target;
  path.hi.array() += target;
  m.bvh.overlapping(path, [&](int t) {
    alpha = std::min(alpha, triangle_crossing(m, t, y0, dy, target, alpha));
  });
  return alpha;
}

}  // namespace

double step_bound(const Model& model, const Points& x0, const Points& x1, double t0, double t1,
                  const std::vector<Contact>& pair_candidates, double slack) {
  double alpha = 1.0;
  const double keep = 1.0 - slack;  // the fraction of each starting gap that must remain
  const int n = model.particle_count();
  for (int i = 0; i < n; ++i) {
    if (model.inv_mass[static_cast<size_t>(i)] <= 0.0) continue;
    const Vec3 a0 = x0.row(i).transpose();
    const Vec3 a1 = x1.row(i).transpose();
    const Vec3 da = a1 - a0;
    const double r = model.radius[static_cast<size_t>(i)];
    for (const PlaneCollider& p : model.planes) {
      const double nn = p.normal.norm();
      const double d0 = (p.normal.dot(a0) + p.offset) / nn - r;
      const double dd = p.normal.dot(da) / nn;
      if (dd < 0.0 && d0 > 0.0) alpha = std::min(alpha, slack * d0 / -dd);  // d0 + alpha dd = keep d0
    }
    for (const SphereCollider& s : model.spheres) {
      const Vec3 c0 = sphere_center(model, s, t0), c1 = sphere_center(model, s, t1);
      const Vec3 p = a0 - c0, q = da - (c1 - c0);
      if (s.side == SphereSide::Outside) {
        const double d0 = p.norm() - (s.radius + r);
        if (d0 <= 0.0) continue;
        alpha = std::min(alpha, radial_crossing(p, q, s.radius + r + keep * d0, true));
      } else {
        if (s.side == SphereSide::Bowl && !below_centre(model, a0, c0) &&
            !below_centre(model, a1, c1))
          continue;
        const double d0 = (s.radius - r) - p.norm();
        if (d0 <= 0.0) continue;
        alpha = std::min(alpha, radial_crossing(p, q, s.radius - r - keep * d0, false));
      }
    }
  }
  for (const MeshCollider& m : model.meshes)
    for (int i = 0; i < n; ++i) {
      if (model.inv_mass[static_cast<size_t>(i)] <= 0.0) continue;
      const Vec3 a0 = x0.row(i).transpose();
      const Vec3 da = x1.row(i).transpose() - a0;
      alpha = mesh_step_bound(model, m, a0, da, model.radius[static_cast<size_t>(i)], t0, t1,
                              keep, alpha);
    }
  for (const Contact& c : pair_candidates) {
    if (c.kind != ContactKind::Particle) continue;
    const Vec3 p = (x0.row(c.a) - x0.row(c.b)).transpose();
    const Vec3 q = (x1.row(c.a) - x1.row(c.b)).transpose() - p;
    const double R = model.radius[static_cast<size_t>(c.a)] + model.radius[static_cast<size_t>(c.b)];
    const double d0 = p.norm() - R;
    if (d0 <= 0.0) continue;
    alpha = std::min(alpha, radial_crossing(p, q, R + keep * d0, true));
  }
  return alpha;
}

}  // namespace pbdbench::barrier

// ---- Surfaces ----------------------------------------------------------------------------------

namespace pbdbench::barrier {

namespace {

using proximity::PairKind;
using X4 = std::array<Vec3, 4>;

X4 gather4(const std::array<int, 4>& v, const Points& x) {
  return {x.row(v[0]).transpose(), x.row(v[1]).transpose(), x.row(v[2]).transpose(),
          x.row(v[3]).transpose()};
}

double pair_distance(const SurfacePair& pair, const X4& y) {
  return pair.kind == PairKind::PointTriangle
             ? proximity::point_triangle_distance(y[0], y[1], y[2], y[3])
             : proximity::edge_edge_distance(y[0], y[1], y[2], y[3]);
}

}  // namespace

Vec3 tangential_displacement(const SurfaceFriction& f, const Points& x, const Points& x0) {
  Vec3 dx = Vec3::Zero();
  for (size_t i = 0; i < 4; ++i)
    dx += f.c[i] * (x.row(f.v[i]) - x0.row(f.v[i])).transpose();
  return dx - f.f.normal * f.f.normal.dot(dx);
}

SurfaceBarrier::SurfaceBarrier(const Model& model) : model_(&model) {
  enabled_ = (model.surface_contact || model.self_contact) && !model.triangles.empty();
  if (!enabled_) return;
  const int n = model.particle_count();
  for (const auto& t : model.triangles)
    for (int k = 0; k < 3; ++k) {
      vertices_.push_back(t[static_cast<size_t>(k)]);
      int a = t[static_cast<size_t>(k)], b = t[static_cast<size_t>((k + 1) % 3)];
      if (a > b) std::swap(a, b);
      edges_.push_back({a, b});
    }
  std::sort(vertices_.begin(), vertices_.end());
  vertices_.erase(std::unique(vertices_.begin(), vertices_.end()), vertices_.end());
  std::sort(edges_.begin(), edges_.end());
  edges_.erase(std::unique(edges_.begin(), edges_.end()), edges_.end());
  for (const auto& e : edges_) edge_as_triangle_.push_back({e[0], e[1], e[1]});
  for (int v : vertices_) max_radius_ = std::max(max_radius_, model.radius[static_cast<size_t>(v)]);
  body_.resize(static_cast<size_t>(n));
  int bodies = 1;
  for (int p = 0; p < n; ++p) {
    body_[static_cast<size_t>(p)] = particle_body(model, p);
    bodies = std::max(bodies, body_[static_cast<size_t>(p)] + 1);
  }
  body_has_tets_.assign(static_cast<size_t>(bodies), 0);
  for (const auto& tet : model.tets) body_has_tets_[static_cast<size_t>(body_[static_cast<size_t>(tet[0])])] = 1;
  if (model.self_contact) {
    neighbours_.assign(static_cast<size_t>(n), {});
    for (const auto& t : model.triangles)
      for (int i = 0; i < 3; ++i)
        for (int j = 0; j < 3; ++j)
          if (i != j) neighbours_[static_cast<size_t>(t[static_cast<size_t>(i)])].push_back(t[static_cast<size_t>(j)]);
    for (auto& list : neighbours_) {
      std::sort(list.begin(), list.end());
      list.erase(std::unique(list.begin(), list.end()), list.end());
    }
  }
}

bool SurfaceBarrier::point_triangle_allowed(int p, int t) const {
  const Model& m = *model_;
  const auto& tri = m.triangles[static_cast<size_t>(t)];
  if (tri[0] == p || tri[1] == p || tri[2] == p) return false;
  bool dynamic = m.inv_mass[static_cast<size_t>(p)] > 0.0;
  for (int v : tri) dynamic = dynamic || m.inv_mass[static_cast<size_t>(v)] > 0.0;
  if (!dynamic) return false;
  const int body = body_[static_cast<size_t>(p)];
  if (body != body_[static_cast<size_t>(tri[0])]) return m.surface_contact;
  if (!m.self_contact || body_has_tets_[static_cast<size_t>(body)]) return false;
  const auto& near = neighbours_[static_cast<size_t>(p)];
  for (int v : tri)
    if (std::binary_search(near.begin(), near.end(), v)) return false;
  return true;
}

bool SurfaceBarrier::edge_edge_allowed(int e, int f) const {
  const Model& m = *model_;
  const auto& a = edges_[static_cast<size_t>(e)];
  const auto& b = edges_[static_cast<size_t>(f)];
  for (int u : a)
    for (int w : b)
      if (u == w) return false;
  bool dynamic = false;
  for (int v : {a[0], a[1], b[0], b[1]}) dynamic = dynamic || m.inv_mass[static_cast<size_t>(v)] > 0.0;
  if (!dynamic) return false;
  const int body = body_[static_cast<size_t>(a[0])];
  if (body != body_[static_cast<size_t>(b[0])]) return m.surface_contact;
  if (!m.self_contact || body_has_tets_[static_cast<size_t>(body)]) return false;
  for (int u : a) {
    const auto& near = neighbours_[static_cast<size_t>(u)];
    for (int w : b)
      if (std::binary_search(near.begin(), near.end(), w)) return false;
  }
  return true;
}

SurfacePair SurfaceBarrier::make_point_triangle(int p, int t) const {
  const Model& m = *model_;
  const auto& tri = m.triangles[static_cast<size_t>(t)];
  SurfacePair pair;
  pair.kind = PairKind::PointTriangle;
  pair.v = {p, tri[0], tri[1], tri[2]};
  pair.first = p;
  pair.second = t;
  double r = 0.0;
  for (int v : tri) r = std::max(r, m.radius[static_cast<size_t>(v)]);
  pair.thickness = m.radius[static_cast<size_t>(p)] + r;
  return pair;
}

SurfacePair SurfaceBarrier::make_edge_edge(int e, int f) const {
  const Model& m = *model_;
  const auto& a = edges_[static_cast<size_t>(e)];
  const auto& b = edges_[static_cast<size_t>(f)];
  SurfacePair pair;
  pair.kind = PairKind::EdgeEdge;
  pair.v = {a[0], a[1], b[0], b[1]};
  pair.first = e;
  pair.second = f;
  const auto r = [&](int v) { return m.radius[static_cast<size_t>(v)]; };
  pair.thickness = std::max(r(a[0]), r(a[1])) + std::max(r(b[0]), r(b[1]));
  const Points& rest = m.rest_positions;
  pair.eps_x = proximity::mollifier_threshold(rest.row(a[0]).transpose(), rest.row(a[1]).transpose(),
                                              rest.row(b[0]).transpose(), rest.row(b[1]).transpose());
  return pair;
}

template <class Visit>
void SurfaceBarrier::candidates(const Points& x0, const Points* x1, double grow, Visit visit) const {
  if (!enabled_) return;
  const Model& m = *model_;
  double M = 0.0;  // the largest displacement of a surface vertex over the paths
  if (x1)
    for (int v : vertices_) M = std::max(M, (x1->row(v) - x0.row(v)).norm());
  std::vector<int> found;
  const auto grown = [&](TriangleBvh::Box box, double pad) {
    box.lo.array() -= pad;
    box.hi.array() += pad;
    return box;
  };
  {
    const TriangleBvh bvh(x0, m.triangles);
    for (int p : vertices_) {
      TriangleBvh::Box box;
      box.grow(Vec3(x0.row(p).transpose()));
      if (x1) box.grow(Vec3(x1->row(p).transpose()));
      found.clear();
      bvh.overlapping(grown(box, grow + M + m.radius[static_cast<size_t>(p)] + max_radius_),
                      [&](int t) { found.push_back(t); });
      std::sort(found.begin(), found.end());
      for (int t : found)
        if (point_triangle_allowed(p, t)) visit(make_point_triangle(p, t));
    }
  }
  const TriangleBvh bvh(x0, edge_as_triangle_);
  for (int e = 0; e < static_cast<int>(edges_.size()); ++e) {
    TriangleBvh::Box box;
    for (int v : edges_[static_cast<size_t>(e)]) {
      box.grow(Vec3(x0.row(v).transpose()));
      if (x1) box.grow(Vec3(x1->row(v).transpose()));
    }
    found.clear();
    bvh.overlapping(grown(box, grow + M + 2.0 * max_radius_), [&](int f) {
      if (f > e) found.push_back(f);
    });
    std::sort(found.begin(), found.end());
    for (int f : found)
      if (edge_edge_allowed(e, f)) visit(make_edge_edge(e, f));
  }
}

std::vector<SurfacePair> SurfaceBarrier::near(const Points& x, double margin) const {
  std::vector<SurfacePair> out;
  candidates(x, nullptr, std::max(margin, 0.0), [&](const SurfacePair& pair) {
    if (gap(pair, x) < margin) out.push_back(pair);
  });
  return out;
}

std::vector<SurfacePair> SurfaceBarrier::swept(const Points& x0, const Points& x1,
                                               double margin) const {
  std::vector<SurfacePair> out;
  candidates(x0, &x1, std::max(margin, 0.0), [&](const SurfacePair& pair) { out.push_back(pair); });
  return out;
}

double SurfaceBarrier::gap(const SurfacePair& pair, const Points& x) {
  return pair_distance(pair, gather4(pair.v, x)) - pair.thickness;
}

SurfaceTerm SurfaceBarrier::term(const SurfacePair& pair, const Points& x, double d_hat) {
  SurfaceTerm out;
  const X4 y = gather4(pair.v, x);
  const bool pt = pair.kind == PairKind::PointTriangle;
  const proximity::Distance dist = pt ? proximity::point_triangle(y[0], y[1], y[2], y[3])
                                      : proximity::edge_edge(y[0], y[1], y[2], y[3]);
  out.gap = dist.d - pair.thickness;
  if (out.gap >= d_hat) return out;
  if (!(out.gap > 0.0)) {
    out.value = kInf;
    return out;
  }
  const double b = value(out.gap, d_hat), b1 = first(out.gap, d_hat), b2 = second(out.gap, d_hat);
  const proximity::Mat12 hb = b2 * dist.grad * dist.grad.transpose() + b1 * dist.hess;
  if (pt) {
    out.value = b;
    out.b_first = b1;
    out.grad = b1 * dist.grad;
    out.hess = hb;
    return out;
  }
  const proximity::Mollifier mo = proximity::edge_edge_mollifier(y[0], y[1], y[2], y[3], pair.eps_x);
  out.value = mo.value * b;
  out.b_first = mo.value * b1;
  out.grad = mo.value * b1 * dist.grad + b * mo.grad;
  const proximity::Mat12 cross = b1 * mo.grad * dist.grad.transpose();
  out.hess = mo.value * hb + cross + cross.transpose() + b * mo.hess;
  return out;
}

double SurfaceBarrier::energy(const SurfacePair& pair, const Points& x, double d_hat) {
  const X4 y = gather4(pair.v, x);
  const double g = pair_distance(pair, y) - pair.thickness;
  if (g >= d_hat) return 0.0;
  if (!(g > 0.0)) return kInf;
  double m = 1.0;
  if (pair.kind == PairKind::EdgeEdge) {
    const double c = (y[1] - y[0]).cross(y[3] - y[2]).squaredNorm();
    if (c < pair.eps_x) m = -c * c / (pair.eps_x * pair.eps_x) + 2.0 * c / pair.eps_x;
  }
  return m * value(g, d_hat);
}

double SurfaceBarrier::step_bound(const Points& x0, const Points& x1, double d_hat, double keep,
                                  double limit, long* iterations) const {
  double alpha = limit;
  if (!enabled_) return alpha;
  for (const SurfacePair& pair : swept(x0, x1, d_hat)) {
    const X4 y0 = gather4(pair.v, x0), y1 = gather4(pair.v, x1);
    X4 dy;
    for (size_t i = 0; i < 4; ++i) dy[i] = y1[i] - y0[i];
    const double g0 = pair_distance(pair, y0) - pair.thickness;
    if (!(g0 > 0.0))
      throw std::logic_error("the surface step bound met a pair that starts with a gap <= 0");
    const proximity::CcdResult r =
        proximity::conservative_ccd(pair.kind, y0, dy, pair.thickness, keep, alpha);
    alpha = r.alpha;
    if (iterations) *iterations += r.iterations;
  }
  return alpha;
}

std::vector<SurfaceFriction> SurfaceBarrier::lag_friction(const Points& x0, double kappa,
                                                          double d_hat) const {
  std::vector<SurfaceFriction> out;
  if (!enabled_ || !(model_->surface_friction > 0.0)) return out;
  for (const SurfacePair& pair : near(x0, d_hat)) {
    const SurfaceTerm t = term(pair, x0, d_hat);
    const double lambda = -kappa * t.b_first;
    if (!(t.gap > 0.0) || !(lambda > 0.0)) continue;
    const X4 y = gather4(pair.v, x0);
    SurfaceFriction f;
    f.v = pair.v;
    Vec3 n;
    if (pair.kind == PairKind::PointTriangle) {
      Vec3 bary;
      const Vec3 q = closest_point_on_triangle(y[0], y[1], y[2], y[3], &bary);
      n = y[0] - q;
      f.c = {1.0, -bary[0], -bary[1], -bary[2]};
    } else {
      double s = 0.0, u = 0.0;
      proximity::edge_edge_closest(y[0], y[1], y[2], y[3], s, u);
      n = (y[0] + s * (y[1] - y[0])) - (y[2] + u * (y[3] - y[2]));
      f.c = {1.0 - s, s, -(1.0 - u), -u};
    }
    if (!(n.norm() > 0.0)) continue;
    f.f.normal = n.normalized();
    f.f.lambda = lambda;
    f.f.mu = model_->surface_friction;
    out.push_back(f);
  }
  return out;
}

}  // namespace pbdbench::barrier
