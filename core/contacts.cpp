#include "core/contacts.hpp"

#include "core/surface_contact.hpp"

#include <algorithm>
#include <stdexcept>
#include <string>
#include <cmath>
#include <cstdint>
#include <utility>

namespace pbdbench {

const char* to_string(ContactKind kind) {
  switch (kind) {
    case ContactKind::Plane: return "plane";
    case ContactKind::Sphere: return "sphere";
    case ContactKind::Particle: return "particle";
    case ContactKind::Mesh: return "mesh";
    case ContactKind::Triangle: return "triangle";
    case ContactKind::Edge: return "edge";
  }
  return "unknown";
}

namespace {

double plane_value(const PlaneCollider& p, const Vec3& x, double r) {
  const double nn = p.normal.norm();
  return (p.normal.dot(x) + p.offset) / nn - r;
}

// Pairs of particles that share a constraint, sorted, for exclusion from particle contact.
std::vector<std::pair<int, int>> constrained_pairs(const Model& model) {
  std::vector<std::pair<int, int>> pairs;
  for (const Constraint& c : model.constraints) {
    const int k = arity(c.kind);
    for (int i = 0; i < k; ++i)
      for (int j = i + 1; j < k; ++j)
        pairs.emplace_back(std::min(c.particles[i], c.particles[j]),
                           std::max(c.particles[i], c.particles[j]));
  }
  std::sort(pairs.begin(), pairs.end());
  pairs.erase(std::unique(pairs.begin(), pairs.end()), pairs.end());
  return pairs;
}

struct CellKey {
  std::int64_t i, j, k;
  auto operator<=>(const CellKey&) const = default;
};

// The grid cell of a coordinate, clamped to +-2^40 so that far-flung particles (an exploding run)
// neither overflow the conversion nor the neighbour arithmetic. Clamping is monotonic, so two
// particles within one cell of each other still land in the same or neighbouring cells.
std::int64_t cell_index(double coordinate, double cell) {
  constexpr double kLimit = 1099511627776.0;  // 2^40
  return static_cast<std::int64_t>(std::clamp(std::floor(coordinate / cell), -kLimit, kLimit));
}

void find_particle_pairs(const Model& model, const Points& x, double margin,
                         std::vector<Contact>& out) {
  const int n = model.particle_count();
  if (n < 2) return;
  double rmax = 0.0;
  for (double r : model.radius) rmax = std::max(rmax, r);
  const double cell = 2.0 * rmax + std::max(margin, 0.0);
  if (!(cell > 0.0)) return;
  std::vector<std::pair<CellKey, int>> keyed;
  keyed.reserve(static_cast<size_t>(n));
  for (int p = 0; p < n; ++p) {
    if (!x.row(p).allFinite()) continue;
    keyed.push_back({{cell_index(x(p, 0), cell), cell_index(x(p, 1), cell), cell_index(x(p, 2), cell)}, p});
  }
  std::sort(keyed.begin(), keyed.end());
  const auto excluded = constrained_pairs(model);
  std::vector<Contact> pairs;
  for (const auto& [key, a] : keyed) {
    for (std::int64_t di = -1; di <= 1; ++di)
      for (std::int64_t dj = -1; dj <= 1; ++dj)
        for (std::int64_t dk = -1; dk <= 1; ++dk) {
          const CellKey nk{key.i + di, key.j + dj, key.k + dk};
          auto lo = std::lower_bound(keyed.begin(), keyed.end(), std::make_pair(nk, -1));
          for (auto it = lo; it != keyed.end() && it->first == nk; ++it) {
            const int b = it->second;
            if (b <= a) continue;
            if (model.inv_mass[a] == 0.0 && model.inv_mass[b] == 0.0) continue;
            const double C = (x.row(a) - x.row(b)).norm() - (model.radius[a] + model.radius[b]);
            if (!(C < margin)) continue;
            if (std::binary_search(excluded.begin(), excluded.end(), std::make_pair(a, b)))
              continue;
            pairs.push_back({ContactKind::Particle, a, b});
            // Equal spheres touch at most 12 neighbours: kMaxPairsPerElement overlapping pairs
            // per particle (core/surface_contact.hpp's limit) means they have collapsed.
            if (pairs.size() > contact_pair_limit(static_cast<size_t>(n)))
              throw ContactPairLimit(
                  "particle contacts: more than " + std::to_string(kMaxPairsPerElement) +
                  " overlapping pairs per particle (" + std::to_string(n) +
                  " particles): they have collapsed onto each other; the run stops before its "
                  "memory grows with the square of their count");
          }
        }
  }
  std::sort(pairs.begin(), pairs.end(),
            [](const Contact& l, const Contact& r) { return std::tie(l.a, l.b) < std::tie(r.a, r.b); });
  out.insert(out.end(), pairs.begin(), pairs.end());
}

}  // namespace

std::vector<Contact> find_contacts(const Model& model, const Points& x, double t, double margin,
                                   SurfaceContactCache* surface_cache) {
  std::vector<Contact> out;
  const int n = model.particle_count();
  // Particle-major loops, so that each kind comes out sorted by (a, b) as documented; a kind
  // the scene does not have costs no pass over the particles.
  for (int a = 0; a < n && !model.planes.empty(); ++a) {
    if (model.inv_mass[a] == 0.0) continue;
    for (int pi = 0; pi < static_cast<int>(model.planes.size()); ++pi) {
      const PlaneCollider& plane = model.planes[static_cast<size_t>(pi)];
      if (plane_value(plane, x.row(a), model.radius[a]) < margin)
        out.push_back({ContactKind::Plane, a, pi});
    }
  }
  const Vec3 up = up_direction(model);
  std::vector<Vec3> centers;
  for (const SphereCollider& s : model.spheres) centers.push_back(sphere_center(model, s, t));
  for (int a = 0; a < n && !model.spheres.empty(); ++a) {
    if (model.inv_mass[a] == 0.0) continue;
    for (int si = 0; si < static_cast<int>(model.spheres.size()); ++si) {
      const SphereCollider& s = model.spheres[static_cast<size_t>(si)];
      const Vec3& c = centers[static_cast<size_t>(si)];
      const Vec3 xa = x.row(a);
      const double dist = (xa - c).norm();
      double C = 0.0;
      switch (s.side) {
        case SphereSide::Outside: C = dist - (s.radius + model.radius[a]); break;
        case SphereSide::Inside: C = (s.radius - model.radius[a]) - dist; break;
        case SphereSide::Bowl:
          if ((xa - c).dot(up) >= 0.0) continue;
          C = (s.radius - model.radius[a]) - dist;
          break;
      }
      if (C < margin) out.push_back({ContactKind::Sphere, a, si});
    }
  }
  for (int mi = 0; mi < static_cast<int>(model.meshes.size()); ++mi) {
    const MeshCollider& mesh = model.meshes[static_cast<size_t>(mi)];
    const Vec3 offset = mesh_offset(model, mesh, t);
    const TriangleBvh::Box& box = mesh.bvh.bounds();
    for (int a = 0; a < n; ++a) {
      if (model.inv_mass[a] == 0.0) continue;
      const Vec3 p = Vec3(x.row(a).transpose()) - offset;
      if (!p.allFinite()) continue;
      const double reach = std::max(margin, 0.0) + model.radius[a];
      // Outside the box by more than the reach: farther from every triangle than that.
      if (box.squared_distance(p) > reach * reach) continue;
      const MeshDistance md = mesh_distance(mesh, p);
      if (md.triangle >= 0 && md.distance - model.radius[a] < margin)
        out.push_back({ContactKind::Mesh, a, mi});
    }
  }
  if (model.particle_contact) find_particle_pairs(model, x, margin, out);
  if (model.surface_contact || model.self_contact) {
    for (const auto& [p, tri] : find_surface_contacts(model, x, margin, surface_cache))
      out.push_back({ContactKind::Triangle, p, tri});
    for (const auto& e : find_edge_contacts(model, x, margin, surface_cache))
      out.push_back({ContactKind::Edge, e[0], e[1], e[2], e[3]});
  }
  return out;
}

ConstraintEval eval_contact(const Model& model, const Contact& contact, const Points& x, double t) {
  ConstraintEval e;
  const Vec3 xa = x.row(contact.a);
  const double ra = model.radius[static_cast<size_t>(contact.a)];
  switch (contact.kind) {
    case ContactKind::Plane: {
      const PlaneCollider& p = model.planes[static_cast<size_t>(contact.b)];
      const double nn = p.normal.norm();
      e.C = plane_value(p, xa, ra);
      e.grad[0] = p.normal / nn;
      e.valid = nn > 0.0;
      return e;
    }
    case ContactKind::Sphere: {
      const SphereCollider& s = model.spheres[static_cast<size_t>(contact.b)];
      const Vec3 d = xa - sphere_center(model, s, t);
      const double dist = d.norm();
      const double sign = s.side == SphereSide::Outside ? 1.0 : -1.0;
      e.C = s.side == SphereSide::Outside ? dist - (s.radius + ra) : (s.radius - ra) - dist;
      e.valid = dist > 0.0;
      if (e.valid) e.grad[0] = sign * d / dist;
      return e;
    }
    case ContactKind::Particle: {
      const Vec3 xb = x.row(contact.b);
      const double rb = model.radius[static_cast<size_t>(contact.b)];
      const Vec3 d = xa - xb;
      const double dist = d.norm();
      e.C = dist - (ra + rb);
      e.valid = dist > 0.0;
      if (e.valid) {
        e.grad[0] = d / dist;
        e.grad[1] = -d / dist;
      }
      return e;
    }
    case ContactKind::Triangle: {
      const auto& tri = model.triangles[static_cast<size_t>(contact.b)];
      const PointTriangle pt = point_triangle(xa, x.row(tri[0]).transpose(), x.row(tri[1]).transpose(),
                                              x.row(tri[2]).transpose());
      e.C = pt.distance - surface_contact_thickness(model, contact.a, contact.b);
      e.grad[0] = pt.normal;
      for (int k = 0; k < 3; ++k) e.grad[static_cast<size_t>(k + 1)] = -pt.bary[k] * pt.normal;
      return e;
    }
    case ContactKind::Edge: {
      const SegmentSegment ss = segment_segment(xa, x.row(contact.b).transpose(),
                                                x.row(contact.c).transpose(), x.row(contact.d).transpose());
      e.C = ss.distance - edge_contact_thickness(model, {contact.a, contact.b, contact.c, contact.d});
      e.grad[0] = (1.0 - ss.s) * ss.normal;
      e.grad[1] = ss.s * ss.normal;
      e.grad[2] = -(1.0 - ss.t) * ss.normal;
      e.grad[3] = -ss.t * ss.normal;
      return e;
    }
    case ContactKind::Mesh: {
      const MeshCollider& mesh = model.meshes[static_cast<size_t>(contact.b)];
      const MeshDistance md = mesh_distance(mesh, xa - mesh_offset(model, mesh, t));
      e.valid = md.triangle >= 0;
      e.C = md.distance - ra;
      e.grad[0] = md.normal;
      return e;
    }
  }
  return e;
}

double contact_restitution(const Model& model, const Contact& c) {
  switch (c.kind) {
    case ContactKind::Plane: return model.planes[static_cast<size_t>(c.b)].restitution;
    case ContactKind::Sphere: return model.spheres[static_cast<size_t>(c.b)].restitution;
    case ContactKind::Particle: return model.particle_restitution;
    case ContactKind::Mesh: return model.meshes[static_cast<size_t>(c.b)].restitution;
    case ContactKind::Triangle: return model.particle_restitution;
    case ContactKind::Edge: return model.particle_restitution;
  }
  return 0.0;
}

double contact_friction(const Model& model, const Contact& c) {
  switch (c.kind) {
    case ContactKind::Plane: return model.planes[static_cast<size_t>(c.b)].friction;
    case ContactKind::Sphere: return model.spheres[static_cast<size_t>(c.b)].friction;
    case ContactKind::Particle: return model.particle_friction;
    case ContactKind::Mesh: return model.meshes[static_cast<size_t>(c.b)].friction;
    case ContactKind::Triangle: return model.surface_friction;
    case ContactKind::Edge: return model.surface_friction;
  }
  return 0.0;
}

int contact_particles(const Model& model, const Contact& c, std::array<int, 4>& out) {
  out = {c.a, -1, -1, -1};
  switch (c.kind) {
    case ContactKind::Particle:
      out[1] = c.b;
      return 2;
    case ContactKind::Triangle: {
      const auto& tri = model.triangles[static_cast<size_t>(c.b)];
      out = {c.a, tri[0], tri[1], tri[2]};
      return 4;
    }
    case ContactKind::Edge:
      out = {c.a, c.b, c.c, c.d};
      return 4;
    default: return 1;
  }
}

Vec3 contact_surface_velocity(const Model& model, const Contact& c, const Points& v, double t) {
  switch (c.kind) {
    case ContactKind::Plane: return Vec3::Zero();
    case ContactKind::Sphere: {
      const SphereCollider& s = model.spheres[static_cast<size_t>(c.b)];
      if (s.motion < 0) return Vec3::Zero();
      return motion_velocity(model.motions[static_cast<size_t>(s.motion)], t);
    }
    case ContactKind::Particle: return v.row(c.b);
    case ContactKind::Mesh: {
      const MeshCollider& m = model.meshes[static_cast<size_t>(c.b)];
      if (m.motion < 0) return Vec3::Zero();
      return motion_velocity(model.motions[static_cast<size_t>(m.motion)], t);
    }
    case ContactKind::Triangle:
    case ContactKind::Edge:
      // The closest point's velocity needs the positions: the velocity pass takes the
      // triangle's (edges') vertices' velocities through the gradient
      // (solver_api/velocity_pass.cpp).
      return Vec3::Zero();
  }
  return Vec3::Zero();
}

}  // namespace pbdbench
