// A triangle mesh as a collider. mesh_collider.hpp.
#include "core/mesh_collider.hpp"

#include <algorithm>
#include <cmath>
#include <map>
#include <sstream>
#include <stdexcept>
#include <string>
#include <utility>

namespace pbdbench {

MeshCollider make_mesh_collider(Points vertices, std::vector<std::array<int, 3>> triangles) {
  MeshCollider m;
  const int nv = static_cast<int>(vertices.rows());
  const int nt = static_cast<int>(triangles.size());
  if (nt == 0) throw MeshColliderError(-1, "the mesh has no triangles");
  if (!vertices.allFinite()) throw MeshColliderError(-1, "a vertex is not finite");
  for (int t = 0; t < nt; ++t)
    for (int k = 0; k < 3; ++k) {
      const int v = triangles[static_cast<size_t>(t)][static_cast<size_t>(k)];
      if (v < 0 || v >= nv)
        throw MeshColliderError(t, "triangle " + std::to_string(t) + " has vertex index " +
                                    std::to_string(v) + ", outside 0.." + std::to_string(nv - 1));
    }
  const Vec3 lo = vertices.colwise().minCoeff().transpose();
  const Vec3 hi = vertices.colwise().maxCoeff().transpose();
  const double diag2 = (hi - lo).squaredNorm();
  m.face_normal.resize(static_cast<size_t>(nt));
  m.edge_normal.resize(static_cast<size_t>(nt));
  m.vertex_normal.assign(static_cast<size_t>(nv), Vec3::Zero());
  // Undirected edge -> the sum of its faces' normals and the directions it is used in.
  struct EdgeUse {
    Vec3 normal = Vec3::Zero();
    int forward = 0, backward = 0;
  };
  std::map<std::pair<int, int>, EdgeUse> edges;
  for (int t = 0; t < nt; ++t) {
    const auto& tri = triangles[static_cast<size_t>(t)];
    const Vec3 a = vertices.row(tri[0]).transpose(), b = vertices.row(tri[1]).transpose(),
               c = vertices.row(tri[2]).transpose();
    const Vec3 n = (b - a).cross(c - a);
    // |n| is twice the area.
    if (!(0.5 * n.norm() > 1e-12 * diag2)) {
      std::ostringstream os;
      os << "triangle " << t << " is degenerate (area " << 0.5 * n.norm()
         << " m^2, at most 1e-12 of the squared bounding-box diagonal: it has no normal)";
      throw MeshColliderError(t, os.str());
    }
    const Vec3 unit = n.normalized();
    m.face_normal[static_cast<size_t>(t)] = unit;
    for (int k = 0; k < 3; ++k) {
      const int i = tri[static_cast<size_t>(k)], j = tri[static_cast<size_t>((k + 1) % 3)],
                l = tri[static_cast<size_t>((k + 2) % 3)];
      EdgeUse& e = edges[{std::min(i, j), std::max(i, j)}];
      e.normal += unit;
      (i < j ? e.forward : e.backward) += 1;
      // The angle of the triangle at vertex i, between the edges to j and to l.
      const Vec3 u = vertices.row(j).transpose() - vertices.row(i).transpose();
      const Vec3 w = vertices.row(l).transpose() - vertices.row(i).transpose();
      const double angle = std::atan2(u.cross(w).norm(), u.dot(w));
      m.vertex_normal[static_cast<size_t>(i)] += angle * unit;
    }
  }
  bool closed = true;
  for (const auto& [key, e] : edges) closed = closed && e.forward == 1 && e.backward == 1;
  m.closed = closed;
  for (int t = 0; t < nt; ++t) {
    const auto& tri = triangles[static_cast<size_t>(t)];
    for (int k = 0; k < 3; ++k) {
      const int i = tri[static_cast<size_t>(k)], j = tri[static_cast<size_t>((k + 1) % 3)];
      const Vec3 s = edges[{std::min(i, j), std::max(i, j)}].normal;
      // Two opposite faces (a sheet folded flat) sum to zero: the face's own normal then.
      m.edge_normal[static_cast<size_t>(t)][static_cast<size_t>(k)] =
          s.norm() > 1e-12 ? Vec3(s.normalized()) : m.face_normal[static_cast<size_t>(t)];
    }
  }
  for (Vec3& n : m.vertex_normal) n = n.norm() > 1e-12 ? Vec3(n.normalized()) : Vec3(Vec3::UnitY());
  m.bvh = TriangleBvh(vertices, triangles);
  m.vertices = std::move(vertices);
  m.triangles = std::move(triangles);
  return m;
}

MeshDistance mesh_distance(const MeshCollider& mesh, const Vec3& p, double max_distance) {
  MeshDistance out;
  const TriangleBvh::Hit hit = mesh.bvh.closest(p, max_distance);
  if (hit.triangle < 0) return out;
  out.triangle = hit.triangle;
  out.point = hit.point;
  const size_t t = static_cast<size_t>(hit.triangle);
  const auto& tri = mesh.triangles[t];
  // The closest feature from the barycentric coordinates: the regions give exact zeros.
  int nonzero = 0;
  for (int k = 0; k < 3; ++k) nonzero += hit.bary[k] != 0.0 ? 1 : 0;
  out.features = nonzero;
  Vec3 pseudo = mesh.face_normal[t];
  Vec3 edge_dir = Vec3::Zero();
  if (nonzero == 1) {
    int k = 0;
    hit.bary.maxCoeff(&k);
    pseudo = mesh.vertex_normal[static_cast<size_t>(tri[static_cast<size_t>(k)])];
  } else if (nonzero == 2) {
    // Edge (k, k+1 mod 3) is the one whose opposite vertex has coordinate 0.
    int zero = 0;
    for (int k = 0; k < 3; ++k)
      if (hit.bary[k] == 0.0) zero = k;
    const int k = (zero + 1) % 3;
    pseudo = mesh.edge_normal[t][static_cast<size_t>(k)];
    edge_dir = (mesh.vertices.row(tri[static_cast<size_t>((k + 1) % 3)]) -
                mesh.vertices.row(tri[static_cast<size_t>(k)]))
                   .transpose()
                   .normalized();
  }
  const Vec3 u = p - hit.point;
  const double d = u.norm();
  out.unsigned_distance = d;
  const double sign = u.dot(pseudo) < 0.0 ? -1.0 : 1.0;
  out.distance = sign * d;
  // On the surface (d below round-off of the mesh's coordinates) the direction is undefined: the
  // pseudo-normal stands for it.
  const double scale = std::max(1.0, p.cwiseAbs().maxCoeff());
  if (d > 1e-14 * scale) {
    const Vec3 g = u / d;
    out.direction = g;
    out.normal = sign * g;
    if (nonzero == 1)
      out.hessian = (Mat3::Identity() - g * g.transpose()) / d;
    else if (nonzero == 2)
      out.hessian = (Mat3::Identity() - edge_dir * edge_dir.transpose() - g * g.transpose()) / d;
  } else {
    out.direction = pseudo;
    out.normal = pseudo;
  }
  return out;
}

}  // namespace pbdbench
