// Vertex–triangle contact. surface_contact.hpp.
#include "core/surface_contact.hpp"

#include <algorithm>
#include <cmath>
#include <sstream>

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

SegmentSegment segment_segment(const Vec3& a, const Vec3& b, const Vec3& c, const Vec3& d) {
  SegmentSegment out;
  const Vec3 d1 = b - a, d2 = d - c, r = a - c;
  const double A = d1.dot(d1), E = d2.dot(d2), F = d2.dot(r);
  double s = 0.0, t = 0.0;
  if (A == 0.0 && E == 0.0) {
    // two points
  } else if (A == 0.0) {
    t = std::clamp(F / E, 0.0, 1.0);
  } else {
    const double C = d1.dot(r);
    if (E == 0.0) {
      s = std::clamp(-C / A, 0.0, 1.0);
    } else {
      const double B = d1.dot(d2), den = A * E - B * B;
      // Parallel (den 0): any s is as close; s = 0, then t for it.
      s = den > 0.0 ? std::clamp((B * F - C * E) / den, 0.0, 1.0) : 0.0;
      t = (B * s + F) / E;
      if (t < 0.0) {
        t = 0.0;
        s = std::clamp(-C / A, 0.0, 1.0);
      } else if (t > 1.0) {
        t = 1.0;
        s = std::clamp((B - C) / A, 0.0, 1.0);
      }
    }
  }
  out.s = s;
  out.t = t;
  const Vec3 u = (a + s * d1) - (c + t * d2);
  out.distance = u.norm();
  if (out.distance > 0.0) {
    out.normal = u / out.distance;
  } else {
    const Vec3 n = d1.cross(d2);
    out.normal = n.norm() > 0.0 ? Vec3(n.normalized()) : Vec3(Vec3::UnitY());
  }
  return out;
}

std::vector<std::array<int, 2>> surface_edges(const Model& model) {
  std::vector<std::array<int, 2>> edges;
  edges.reserve(3 * model.triangles.size());
  for (const auto& t : model.triangles)
    for (int k = 0; k < 3; ++k) {
      const int i = t[static_cast<size_t>(k)], j = t[static_cast<size_t>((k + 1) % 3)];
      if (i != j) edges.push_back({std::min(i, j), std::max(i, j)});
    }
  std::sort(edges.begin(), edges.end());
  edges.erase(std::unique(edges.begin(), edges.end()), edges.end());
  return edges;
}

double edge_contact_thickness(const Model& model, const std::array<int, 4>& p) {
  const auto r = [&](int i) { return model.radius[static_cast<size_t>(p[static_cast<size_t>(i)])]; };
  return std::max(r(0), r(1)) + std::max(r(2), r(3));
}

double surface_contact_thickness(const Model& model, int particle, int triangle) {
  const auto& t = model.triangles[static_cast<size_t>(triangle)];
  double r = 0.0;
  for (int v : t) r = std::max(r, model.radius[static_cast<size_t>(v)]);
  return model.radius[static_cast<size_t>(particle)] + r;
}

std::string contact_pair_limit_message(const std::string& what, std::size_t elements,
                                       const std::string& unit, double margin) {
  std::ostringstream text;
  text << what << ": more than " << contact_pair_limit(elements) << " pairs (" << kMaxPairsPerElement
       << " for each of " << elements << " " << unit << ", and " << kPairSlack
       << ") within the contact margin (" << margin
       << " m) plus the radii: the radius spans several mesh spacings and the surfaces lie inside "
          "one another; the search stops before its memory grows with the square of their count "
          "(core/surface_contact.hpp)";
  return text.str();
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

  bool edge_allowed(const std::array<int, 2>& e, const std::array<int, 2>& f) const {
    for (int u : e)
      for (int v : f)
        if (u == v) return false;
    bool dynamic = false;
    for (int v : {e[0], e[1], f[0], f[1]}) dynamic = dynamic || model_.inv_mass[static_cast<size_t>(v)] > 0.0;
    if (!dynamic) return false;
    const int body = particle_body(model_, e[0]);
    if (body != particle_body(model_, f[0])) return model_.surface_contact;
    if (!model_.self_contact || has_tets_[static_cast<size_t>(body)]) return false;
    for (int u : e) {
      const auto& near = neighbours_[static_cast<size_t>(u)];
      for (int v : f)
        if (std::binary_search(near.begin(), near.end(), v)) return false;
    }
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

bool edge_pair_allowed(const Model& model, const std::array<int, 2>& e, const std::array<int, 2>& f) {
  return PairRules(model).edge_allowed(e, f);
}

namespace {

std::vector<std::array<int, 3>> edge_segments(const std::vector<std::array<int, 2>>& edges) {
  std::vector<std::array<int, 3>> segs;
  segs.reserve(edges.size());
  for (const auto& e : edges) segs.push_back({e[0], e[1], e[1]});
  return segs;
}

// A BVH over those of `elements` (triangles, or segments (i, j, j)) whose vertices are finite at
// x (an exploding run keeps going until its detector stops it); index[k] is the element of the
// tree's k. False when none is.
bool finite_bvh(const Points& x, const std::vector<std::array<int, 3>>& elements, TriangleBvh& bvh,
                std::vector<int>& index) {
  std::vector<std::array<int, 3>> kept;
  kept.reserve(elements.size());
  index.clear();
  index.reserve(elements.size());
  for (int k = 0; k < static_cast<int>(elements.size()); ++k) {
    const auto& el = elements[static_cast<size_t>(k)];
    bool finite = true;
    for (int v : el) finite = finite && x.row(v).allFinite();
    if (!finite) continue;
    kept.push_back(el);
    index.push_back(k);
  }
  if (kept.empty()) return false;
  if (x.allFinite()) {
    bvh = TriangleBvh(x, kept);
    return true;
  }
  // The BVH refuses non-finite vertices, also those no kept element uses: zeroed in a copy.
  Points finite = x;
  for (Eigen::Index i = 0; i < finite.rows(); ++i)
    if (!finite.row(i).allFinite()) finite.row(i).setZero();
  bvh = TriangleBvh(finite, kept);
  return true;
}

}  // namespace

const TriangleBvh& SurfaceContactCache::update(Tree& tree,
                                               const std::vector<std::array<int, 3>>& triangles,
                                               const Points& x) {
  const bool same = tree.valid && tree.bvh.vertex_count() == static_cast<int>(x.rows()) &&
                    tree.triangles == triangles;
  if (same) {
    tree.bvh.refit(x);
    if (!(tree.bvh.box_area() > kRebuildFactor * tree.built_area)) {
      ++refits_;
      return tree.bvh;
    }
  }
  tree.bvh = TriangleBvh(x, triangles);
  tree.triangles = triangles;
  tree.built_area = tree.bvh.box_area();
  tree.valid = true;
  ++builds_;
  return tree.bvh;
}

const TriangleBvh& SurfaceContactCache::triangles(const Model& model, const Points& x) {
  return update(tri_, model.triangles, x);
}

const std::vector<std::array<int, 2>>& SurfaceContactCache::edge_list(const Model& model) {
  if (edge_source_ != model.triangles || (edge_list_.empty() && !model.triangles.empty())) {
    edge_source_ = model.triangles;
    edge_list_ = surface_edges(model);
    edge_segments_ = edge_segments(edge_list_);
  }
  return edge_list_;
}

const TriangleBvh& SurfaceContactCache::edges(const Model& model, const Points& x) {
  edge_list(model);
  return update(edge_, edge_segments_, x);
}

std::vector<std::pair<int, int>> find_surface_contacts(const Model& model, const Points& x,
                                                       double margin, SurfaceContactCache* cache) {
  std::vector<std::pair<int, int>> out;
  if (!model.surface_contact && !model.self_contact) return out;
  const int nt = static_cast<int>(model.triangles.size());
  if (nt == 0) return out;
  // With every position finite and a cache: its tree, whose triangle k is the model's k.
  // Otherwise a BVH over the triangles whose vertices are finite (an exploding run keeps going
  // until its detector stops it); `index` maps the BVH's triangles back to the model's.
  const bool cached = cache != nullptr && x.allFinite();
  if (cache != nullptr && !cached) cache->clear();
  std::vector<int> index;
  TriangleBvh fresh;
  if (!cached && !finite_bvh(x, model.triangles, fresh, index)) return out;
  const TriangleBvh& bvh = cached ? cache->triangles(model, x) : fresh;
  const PairRules rules(model);
  double rmax = 0.0;
  for (double r : model.radius) rmax = std::max(rmax, r);
  const int n = model.particle_count();
  const std::size_t limit = contact_pair_limit(static_cast<std::size_t>(n));
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
    bvh.overlapping(box, [&](int k) { found.push_back(cached ? k : index[static_cast<size_t>(k)]); });
    std::sort(found.begin(), found.end());
    for (int t : found) {
      if (!rules.allowed(p, t)) continue;
      const auto& tri = model.triangles[static_cast<size_t>(t)];
      const PointTriangle pt = point_triangle(xp, x.row(tri[0]).transpose(), x.row(tri[1]).transpose(),
                                              x.row(tri[2]).transpose());
      if (pt.distance - surface_contact_thickness(model, p, t) < margin) out.emplace_back(p, t);
      if (out.size() > limit)
        throw ContactPairLimit(contact_pair_limit_message("vertex-triangle contacts", static_cast<std::size_t>(n),
                                                          "particles", margin));
    }
  }
  return out;
}

std::vector<std::array<int, 4>> find_edge_contacts(const Model& model, const Points& x,
                                                   double margin, SurfaceContactCache* cache) {
  std::vector<std::array<int, 4>> out;
  if ((!model.surface_contact && !model.self_contact) || !model.edge_contact) return out;
  if (model.triangles.empty()) return out;
  const bool cached = cache != nullptr && x.allFinite();
  if (cache != nullptr && !cached) cache->clear();
  std::vector<std::array<int, 2>> own;
  if (!cached) own = surface_edges(model);
  const std::vector<std::array<int, 2>>& edges = cached ? cache->edge_list(model) : own;
  // Without a cache: the tree over the edges with finite ends (index: back to `edges`).
  std::vector<int> index;
  TriangleBvh fresh;
  if (!cached && !finite_bvh(x, edge_segments(edges), fresh, index)) return out;
  const TriangleBvh& bvh = cached ? cache->edges(model, x) : fresh;
  const PairRules rules(model);
  double rmax = 0.0;
  for (double r : model.radius) rmax = std::max(rmax, r);
  const std::size_t limit = contact_pair_limit(edges.size());
  std::vector<int> found;
  for (int k = 0; k < static_cast<int>(edges.size()); ++k) {
    const auto& e = edges[static_cast<size_t>(k)];
    const Vec3 xa = x.row(e[0]).transpose(), xb = x.row(e[1]).transpose();
    if (!xa.allFinite() || !xb.allFinite()) continue;
    const double reach = std::max(margin, 0.0) + 2.0 * rmax;
    TriangleBvh::Box box;
    box.grow(xa);
    box.grow(xb);
    box.lo.array() -= reach;
    box.hi.array() += reach;
    found.clear();
    bvh.overlapping(box, [&](int j) {
      const int other = cached ? j : index[static_cast<size_t>(j)];
      if (other > k) found.push_back(other);
    });
    std::sort(found.begin(), found.end());
    for (int j : found) {
      const auto& f = edges[static_cast<size_t>(j)];
      if (!rules.edge_allowed(e, f)) continue;
      const std::array<int, 4> ps{e[0], e[1], f[0], f[1]};
      const SegmentSegment ss = segment_segment(xa, xb, x.row(f[0]).transpose(), x.row(f[1]).transpose());
      if (ss.distance - edge_contact_thickness(model, ps) < margin) out.push_back(ps);
      if (out.size() > limit)
        throw ContactPairLimit(contact_pair_limit_message("edge-edge contacts", edges.size(), "edges", margin));
    }
  }
  return out;
}

}  // namespace pbdbench
