// Vertex–triangle contact. surface_contact.hpp.
#include "core/surface_contact.hpp"

#include <algorithm>
#include <cmath>

#include "core/bvh.hpp"

namespace pbdbench {

PointTriangle point_triangle(const Vec3& p, const Vec3& a, const Vec3& b, const Vec3& c) {
  PointTriangle out;
  const Vec3 q = closest_point_on_triangle(p, a, b, c, &out.bary);
  const Vec3 u = p - q;
  out.distance = u.norm();
  if (out.distance > 0.0) {
    out.normal = u / out.distance;
  } else {
    const Vec3 n = (b - a).cross(c - a);
    out.normal = n.norm() > 0.0 ? Vec3(n.normalized()) : Vec3(Vec3::UnitY());
  }
  return out;
}

double surface_contact_thickness(const Model& model, int particle, int triangle) {
  const auto& t = model.triangles[static_cast<size_t>(triangle)];
  double r = 0.0;
  for (int v : t) r = std::max(r, model.radius[static_cast<size_t>(v)]);
  return model.radius[static_cast<size_t>(particle)] + r;
}

int particle_body(const Model& model, int particle) {
  return model.particle_body.empty() ? 0 : model.particle_body[static_cast<size_t>(particle)];
}

namespace {

// The rules of surface_contact.hpp as tables built once: each particle's body, which bodies have
// tets, and (with self-contact) each particle's neighbours through the triangles, sorted.
class PairRules {
 public:
  explicit PairRules(const Model& model) : model_(model) {
    const int n = model.particle_count();
    int bodies = 1;
    for (int p = 0; p < n; ++p) bodies = std::max(bodies, particle_body(model, p) + 1);
    has_tets_.assign(static_cast<size_t>(bodies), 0);
    for (const auto& tet : model.tets) has_tets_[static_cast<size_t>(particle_body(model, tet[0]))] = 1;
    if (!model.self_contact) return;
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

  bool allowed(int p, int triangle) const {
    const auto& t = model_.triangles[static_cast<size_t>(triangle)];
    if (t[0] == p || t[1] == p || t[2] == p) return false;
    bool dynamic = model_.inv_mass[static_cast<size_t>(p)] > 0.0;
    for (int v : t) dynamic = dynamic || model_.inv_mass[static_cast<size_t>(v)] > 0.0;
    if (!dynamic) return false;
    const int body = particle_body(model_, p);
    if (body != particle_body(model_, t[0])) return model_.surface_contact;
    if (!model_.self_contact || has_tets_[static_cast<size_t>(body)]) return false;
    const auto& near = neighbours_[static_cast<size_t>(p)];
    for (int v : t)
      if (std::binary_search(near.begin(), near.end(), v)) return false;
    return true;
  }

 private:
  const Model& model_;
  std::vector<char> has_tets_;
  std::vector<std::vector<int>> neighbours_;
};

}  // namespace

bool surface_pair_allowed(const Model& model, int particle, int triangle) {
  return PairRules(model).allowed(particle, triangle);
}

std::vector<std::pair<int, int>> find_surface_contacts(const Model& model, const Points& x,
                                                       double margin) {
  std::vector<std::pair<int, int>> out;
  if (!model.surface_contact && !model.self_contact) return out;
  const int nt = static_cast<int>(model.triangles.size());
  if (nt == 0) return out;
  // The BVH over the triangles whose vertices are finite (an exploding run keeps going until
  // its detector stops it); `index` maps the BVH's triangles back to the model's.
  std::vector<std::array<int, 3>> tris;
  std::vector<int> index;
  tris.reserve(static_cast<size_t>(nt));
  index.reserve(static_cast<size_t>(nt));
  bool all_finite = true;
  for (int t = 0; t < nt; ++t) {
    const auto& tri = model.triangles[static_cast<size_t>(t)];
    bool finite = true;
    for (int v : tri) finite = finite && x.row(v).allFinite();
    if (!finite) {
      all_finite = false;
      continue;
    }
    tris.push_back(tri);
    index.push_back(t);
  }
  if (tris.empty()) return out;
  // The BVH refuses non-finite vertices, also those no kept triangle uses: zeroed in a copy.
  Points finite;
  if (!all_finite || !x.allFinite()) {
    finite = x;
    for (Eigen::Index i = 0; i < finite.rows(); ++i)
      if (!finite.row(i).allFinite()) finite.row(i).setZero();
  }
  const TriangleBvh bvh(finite.rows() > 0 ? finite : x, tris);
  const PairRules rules(model);
  double rmax = 0.0;
  for (double r : model.radius) rmax = std::max(rmax, r);
  const int n = model.particle_count();
  std::vector<int> found;
  for (int p = 0; p < n; ++p) {
    const Vec3 xp = x.row(p).transpose();
    if (!xp.allFinite()) continue;
    const double reach = std::max(margin, 0.0) + model.radius[static_cast<size_t>(p)] + rmax;
    TriangleBvh::Box box;
    box.grow(xp);
    box.lo.array() -= reach;
    box.hi.array() += reach;
    found.clear();
    bvh.overlapping(box, [&](int k) { found.push_back(index[static_cast<size_t>(k)]); });
    std::sort(found.begin(), found.end());
    for (int t : found) {
      if (!rules.allowed(p, t)) continue;
      const auto& tri = model.triangles[static_cast<size_t>(t)];
      const PointTriangle pt = point_triangle(xp, x.row(tri[0]).transpose(), x.row(tri[1]).transpose(),
                                              x.row(tri[2]).transpose());
      if (pt.distance - surface_contact_thickness(model, p, t) < margin) out.emplace_back(p, t);
    }
  }
  return out;
}

}  // namespace pbdbench
