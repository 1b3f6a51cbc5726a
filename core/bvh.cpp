// A bounding volume hierarchy over a static triangle mesh. bvh.hpp.
#include "core/bvh.hpp"

#include <algorithm>
#include <cmath>
#include <stdexcept>
#include <string>

namespace pbdbench {

Vec3 closest_point_on_triangle(const Vec3& p, const Vec3& a, const Vec3& b, const Vec3& c,
                               Vec3* bary) {
  auto out = [&](double u, double v, double w) {
    if (bary) *bary = Vec3(u, v, w);
    return Vec3(u * a + v * b + w * c);
  };
  const Vec3 ab = b - a, ac = c - a, ap = p - a;
  const double d1 = ab.dot(ap), d2 = ac.dot(ap);
  if (d1 <= 0.0 && d2 <= 0.0) return out(1, 0, 0);  // vertex a
  const Vec3 bp = p - b;
  const double d3 = ab.dot(bp), d4 = ac.dot(bp);
  if (d3 >= 0.0 && d4 <= d3) return out(0, 1, 0);  // vertex b
  const double vc = d1 * d4 - d3 * d2;
  if (vc <= 0.0 && d1 >= 0.0 && d3 <= 0.0) {  // edge ab
    const double v = d1 - d3 != 0.0 ? d1 / (d1 - d3) : 0.0;
    return out(1 - v, v, 0);
  }
  const Vec3 cp = p - c;
  const double d5 = ab.dot(cp), d6 = ac.dot(cp);
  if (d6 >= 0.0 && d5 <= d6) return out(0, 0, 1);  // vertex c
  const double vb = d5 * d2 - d1 * d6;
  if (vb <= 0.0 && d2 >= 0.0 && d6 <= 0.0) {  // edge ac
    const double w = d2 - d6 != 0.0 ? d2 / (d2 - d6) : 0.0;
    return out(1 - w, 0, w);
  }
  const double va = d3 * d6 - d5 * d4;
  if (va <= 0.0 && (d4 - d3) >= 0.0 && (d5 - d6) >= 0.0) {  // edge bc
    const double den = (d4 - d3) + (d5 - d6);
    const double w = den != 0.0 ? (d4 - d3) / den : 0.0;
    return out(0, 1 - w, w);
  }
  const double sum = va + vb + vc;  // the face; > 0 here unless the triangle is degenerate
  if (!(sum > 0.0)) {
    // Degenerate (collinear or coincident vertices): the closest of the three edges.
    Vec3 best = a, bb = Vec3::Zero();
    double bd = 1e300;
    const std::array<std::array<const Vec3*, 2>, 3> edges{{{&a, &b}, {&b, &c}, {&a, &c}}};
    for (int e = 0; e < 3; ++e) {
      const Vec3& s = *edges[e][0];
      const Vec3 d = *edges[e][1] - s;
      const double L = d.squaredNorm();
      const double t = L > 0.0 ? std::clamp((p - s).dot(d) / L, 0.0, 1.0) : 0.0;
      const Vec3 q = s + t * d;
      if ((p - q).squaredNorm() < bd) {
        bd = (p - q).squaredNorm();
        best = q;
        bb = e == 0 ? Vec3(1 - t, t, 0) : e == 1 ? Vec3(0, 1 - t, t) : Vec3(1 - t, 0, t);
      }
    }
    if (bary) *bary = bb;
    return best;
  }
  const double v = vb / sum, w = vc / sum;
  return out(1 - v - w, v, w);
}

double TriangleBvh::Box::squared_distance(const Vec3& p) const {
  const Vec3 d = (lo - p).cwiseMax(Vec3::Zero()).cwiseMax(p - hi);
  return d.squaredNorm();
}

bool TriangleBvh::Box::overlaps(const Box& b) const {
  return (lo.array() <= b.hi.array()).all() && (b.lo.array() <= hi.array()).all();
}

namespace {
thread_local long g_visits = 0;
}

long TriangleBvh::last_visits() { return g_visits; }

TriangleBvh::TriangleBvh(const Points& vertices, const std::vector<std::array<int, 3>>& triangles)
    : vertices_(vertices), triangles_(triangles) {
  const int nv = static_cast<int>(vertices.rows());
  if (!vertices.allFinite()) throw std::invalid_argument("TriangleBvh: a vertex is not finite");
  const int nt = static_cast<int>(triangles.size());
  tri_box_.resize(static_cast<size_t>(nt));
  centroid_.resize(static_cast<size_t>(nt));
  for (int t = 0; t < nt; ++t) {
    Box b;
    Vec3 c = Vec3::Zero();
    for (int k = 0; k < 3; ++k) {
      const int v = triangles[static_cast<size_t>(t)][static_cast<size_t>(k)];
      if (v < 0 || v >= nv)
        throw std::invalid_argument("TriangleBvh: triangle " + std::to_string(t) + " has vertex " +
                                    std::to_string(v) + ", outside 0.." + std::to_string(nv - 1));
      b.grow(Vec3(vertices.row(v).transpose()));
      c += vertices.row(v).transpose();
    }
    tri_box_[static_cast<size_t>(t)] = b;
    centroid_[static_cast<size_t>(t)] = c / 3.0;
  }
  order_.resize(static_cast<size_t>(nt));
  for (int t = 0; t < nt; ++t) order_[static_cast<size_t>(t)] = t;
  nodes_.reserve(static_cast<size_t>(2 * (nt / kLeafSize + 1)));
  if (nt > 0) build(0, nt);
}

int TriangleBvh::build(int first, int count) {
  const int id = static_cast<int>(nodes_.size());
  nodes_.emplace_back();
  Box box, cbox;
  for (int i = first; i < first + count; ++i) {
    box.grow(tri_box_[static_cast<size_t>(order_[static_cast<size_t>(i)])]);
    cbox.grow(centroid_[static_cast<size_t>(order_[static_cast<size_t>(i)])]);
  }
  nodes_[static_cast<size_t>(id)].box = box;
  if (count <= kLeafSize) {
    nodes_[static_cast<size_t>(id)].first = first;
    nodes_[static_cast<size_t>(id)].count = count;
    return id;
  }
  int axis = 0;
  (cbox.hi - cbox.lo).maxCoeff(&axis);
  const int mid = first + count / 2;
  // Median split; ties broken by triangle index, so the tree does not depend on the sort's whims.
  std::nth_element(order_.begin() + first, order_.begin() + mid, order_.begin() + first + count,
                   [&](int a, int b) {
                     const double ca = centroid_[static_cast<size_t>(a)][axis];
                     const double cb = centroid_[static_cast<size_t>(b)][axis];
                     return ca < cb || (ca == cb && a < b);
                   });
  const int left = build(first, mid - first);
  const int right = build(mid, first + count - mid);
  nodes_[static_cast<size_t>(id)].left = left;
  nodes_[static_cast<size_t>(id)].right = right;
  return id;
}

void TriangleBvh::refit(const Points& vertices) {
  if (vertices.rows() != vertices_.rows())
    throw std::invalid_argument("TriangleBvh::refit: " + std::to_string(vertices.rows()) +
                                " vertices for a mesh of " + std::to_string(vertices_.rows()));
  if (!vertices.allFinite()) throw std::invalid_argument("TriangleBvh::refit: a vertex is not finite");
  vertices_ = vertices;
  const int nt = triangle_count();
  for (int t = 0; t < nt; ++t) {
    Box b;
    for (int v : triangles_[static_cast<size_t>(t)]) b.grow(Vec3(vertices_.row(v).transpose()));
    tri_box_[static_cast<size_t>(t)] = b;
  }
  // build() numbers a node before its children: in reverse order, children come first.
  for (size_t id = nodes_.size(); id-- > 0;) {
    Node& n = nodes_[id];
    Box b;
    if (n.left < 0) {
      for (int i = n.first; i < n.first + n.count; ++i)
        b.grow(tri_box_[static_cast<size_t>(order_[static_cast<size_t>(i)])]);
    } else {
      b.grow(nodes_[static_cast<size_t>(n.left)].box);
      b.grow(nodes_[static_cast<size_t>(n.right)].box);
    }
    n.box = b;
  }
}

double TriangleBvh::box_area() const {
  double area = 0.0;
  for (const Node& n : nodes_) {
    const Vec3 d = (n.box.hi - n.box.lo).cwiseMax(Vec3::Zero());
    area += 2.0 * (d.x() * d.y() + d.y() * d.z() + d.z() * d.x());
  }
  return area;
}

const TriangleBvh::Box& TriangleBvh::bounds() const {
  static const Box empty;
  return nodes_.empty() ? empty : nodes_[0].box;
}

TriangleBvh::Hit TriangleBvh::closest(const Vec3& p, double max_distance) const {
  Hit hit;
  g_visits = 0;
  if (nodes_.empty()) return hit;
  double best = max_distance * max_distance;
  // Depth first, nearer child first; a node is skipped when its box is farther than the best.
  // The stack holds at most one pending sibling per level (median splits: depth < 64 for any
  // mesh that fits in memory), so it lives on the stack, not the heap.
  std::array<int, 128> stack;
  int top = 0;
  stack[static_cast<size_t>(top++)] = 0;
  while (top > 0) {
    const int id = stack[static_cast<size_t>(--top)];
    const Node& n = nodes_[static_cast<size_t>(id)];
    ++g_visits;
    if (n.box.squared_distance(p) > best) continue;
    if (n.left < 0) {
      for (int i = n.first; i < n.first + n.count; ++i) {
        const int t = order_[static_cast<size_t>(i)];
        const auto& tri = triangles_[static_cast<size_t>(t)];
        Vec3 bary;
        const Vec3 q = closest_point_on_triangle(p, vertices_.row(tri[0]).transpose(),
                                                 vertices_.row(tri[1]).transpose(),
                                                 vertices_.row(tri[2]).transpose(), &bary);
        const double d2 = (p - q).squaredNorm();
        if (d2 < best || (d2 == best && (hit.triangle < 0 || t < hit.triangle))) {
          best = d2;
          hit.triangle = t;
          hit.point = q;
          hit.bary = bary;
        }
      }
      continue;
    }
    const double dl = nodes_[static_cast<size_t>(n.left)].box.squared_distance(p);
    const double dr = nodes_[static_cast<size_t>(n.right)].box.squared_distance(p);
    // Push the farther first, so the nearer is visited first.
    if (dl <= dr) {
      stack[static_cast<size_t>(top++)] = n.right;
      stack[static_cast<size_t>(top++)] = n.left;
    } else {
      stack[static_cast<size_t>(top++)] = n.left;
      stack[static_cast<size_t>(top++)] = n.right;
    }
  }
  if (hit.triangle >= 0) hit.distance = std::sqrt(best);
  return hit;
}

void TriangleBvh::overlapping(const Box& box, const std::function<void(int)>& visit) const {
  if (nodes_.empty()) return;
  std::vector<int> stack{0};
  while (!stack.empty()) {
    const Node& n = nodes_[static_cast<size_t>(stack.back())];
    stack.pop_back();
    if (!n.box.overlaps(box)) continue;
    if (n.left < 0) {
      for (int i = n.first; i < n.first + n.count; ++i) {
        const int t = order_[static_cast<size_t>(i)];
        if (tri_box_[static_cast<size_t>(t)].overlaps(box)) visit(t);
      }
      continue;
    }
    stack.push_back(n.right);
    stack.push_back(n.left);
  }
}

}  // namespace pbdbench
