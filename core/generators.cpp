// Scene generators (core/generators.hpp). Each validates its spec first and throws
// std::invalid_argument naming the field and the bound it breaks, then appends to the model.
// Rest values of the constraints are measured on the generated geometry, so every constraint
// has C = 0 in the rest configuration.
#include "core/generators.hpp"

#include <algorithm>
#include <cmath>
#include <numbers>
#include <random>
#include <stdexcept>
#include <string>
#include <vector>

#include "core/build_helpers.hpp"
#include "core/mesh_io.hpp"

namespace pbdbench {

using namespace core::detail;  // core/build_helpers.hpp

namespace {

// Pins a particle where it is: inv_mass 0 and a static Attachment.
void pin(Model& model, int particle) {
  model.inv_mass[static_cast<size_t>(particle)] = 0.0;
  Attachment a;
  a.particle = particle;
  a.anchor = model.rest_positions.row(particle).transpose();
  a.motion = -1;
  model.attachments.push_back(a);
}

}  // namespace

// ---------------------------------------------------------------------------------------------

int add_particle(Model& model, const Vec3& position, double mass, double radius) {
  require_finite("add_particle position", position);
  require_positive("add_particle mass", mass);
  require_positive("add_particle radius", radius);
  Points x(1, 3);
  x.row(0) = position.transpose();
  return append_particles(model, x, {mass}, radius);
}

ParticleRange add_chain(Model& model, const ChainSpec& spec) {
  require_min("ChainSpec.links", spec.links, 1);
  require_positive("ChainSpec.link_length", spec.link_length);
  require_finite("ChainSpec.top", spec.top);
  require_finite("ChainSpec.direction", spec.direction);
  // The direction must be a unit vector: a silently normalised one would hide a scenario typo.
  if (!(std::abs(spec.direction.norm() - 1.0) <= 1e-6))
    throw std::invalid_argument("ChainSpec.direction has norm " +
                                format_number(spec.direction.norm(), kExactDigits) +
                                ", must be a unit vector (|norm - 1| <= 1e-6)");
  require_positive("ChainSpec.mass", spec.mass);
  require_non_negative("ChainSpec.end_mass", spec.end_mass);
  require_positive("ChainSpec.radius", spec.radius);
  require_params("ChainSpec.link", spec.link);

  const int n = spec.links + 1;
  Points x(n, 3);
  std::vector<double> masses(static_cast<size_t>(n), spec.mass);
  for (int k = 0; k < n; ++k)
    x.row(k) = (spec.top + static_cast<double>(k) * spec.link_length * spec.direction).transpose();
  if (spec.end_mass > 0.0) masses.back() = spec.end_mass;

  const int begin = append_particles(model, x, masses, spec.radius);
  const std::uint16_t group = model.group_index("link");
  for (int k = 0; k < spec.links; ++k) {
    model.edges.push_back({begin + k, begin + k + 1});
    add_distance(model, begin + k, begin + k + 1, spec.link, group);
  }
  if (spec.pin_top) pin(model, begin);
  return {begin, begin + n};
}

ParticleRange add_cloth(Model& model, const ClothSpec& spec) {
  require_min("ClothSpec.nx", spec.nx, 2);
  require_min("ClothSpec.ny", spec.ny, 2);
  require_positive("ClothSpec.width", spec.width);
  require_positive("ClothSpec.height", spec.height);
  require_finite("ClothSpec.origin", spec.origin);
  if (spec.plane != "xz" && spec.plane != "xy")
    throw std::invalid_argument("ClothSpec.plane = \"" + spec.plane +
                                "\" is not one of \"xz\", \"xy\"");
  require_positive("ClothSpec.mass", spec.mass);
  require_positive("ClothSpec.radius", spec.radius);
  require_params("ClothSpec.stretch", spec.stretch);
  require_params("ClothSpec.shear_params", spec.shear_params);
  require_params("ClothSpec.bending_params", spec.bending_params);

  const int nx = spec.nx, ny = spec.ny, n = nx * ny;
  const double dx = spec.width / (nx - 1), dy = spec.height / (ny - 1);
  Points x(n, 3);
  for (int j = 0; j < ny; ++j)
    for (int i = 0; i < nx; ++i) {
      const Vec3 offset = spec.plane == "xz" ? Vec3(i * dx, 0.0, j * dy) : Vec3(i * dx, -j * dy, 0.0);
      x.row(j * nx + i) = (spec.origin + offset).transpose();
    }
  const int begin = append_particles(model, x, std::vector<double>(static_cast<size_t>(n), spec.mass / n),
                                     spec.radius);
  auto id = [&](int i, int j) { return begin + j * nx + i; };

  // Stretch: the grid edges, rows first, then columns. They are also the model's edges.
  const std::uint16_t stretch = model.group_index("stretch");
  for (int j = 0; j < ny; ++j)
    for (int i = 0; i + 1 < nx; ++i) {
      model.edges.push_back({id(i, j), id(i + 1, j)});
      add_distance(model, id(i, j), id(i + 1, j), spec.stretch, stretch);
    }
  for (int j = 0; j + 1 < ny; ++j)
    for (int i = 0; i < nx; ++i) {
      model.edges.push_back({id(i, j), id(i, j + 1)});
      add_distance(model, id(i, j), id(i, j + 1), spec.stretch, stretch);
    }

  // Shear: both diagonals of every cell.
  if (spec.shear) {
    const std::uint16_t shear = model.group_index("shear");
    for (int j = 0; j + 1 < ny; ++j)
      for (int i = 0; i + 1 < nx; ++i) {
        add_distance(model, id(i, j), id(i + 1, j + 1), spec.shear_params, shear);
        add_distance(model, id(i + 1, j), id(i, j + 1), spec.shear_params, shear);
      }
  }

  // Triangles: (00, 01, 11) and (00, 11, 10) per cell, split along the (i, j)-(i+1, j+1)
  // diagonal. The normal points along +y for plane "xz" and +z for plane "xy".
  std::vector<std::array<int, 3>> triangles;
  triangles.reserve(static_cast<size_t>(2 * (nx - 1) * (ny - 1)));
  for (int j = 0; j + 1 < ny; ++j)
    for (int i = 0; i + 1 < nx; ++i) {
      triangles.push_back({id(i, j), id(i, j + 1), id(i + 1, j + 1)});
      triangles.push_back({id(i, j), id(i + 1, j + 1), id(i + 1, j)});
    }
  model.triangles.insert(model.triangles.end(), triangles.begin(), triangles.end());
  model.surface_closed = false;  // a sheet has a boundary

  if (spec.bending) {
    const std::uint16_t bending = model.group_index("bending");
    if (spec.bending_model == BendingModel::Dihedral) {
      add_dihedral_bending(model, triangles, spec.bending_params, bending);
    } else {
      for (int j = 0; j < ny; ++j)
        for (int i = 0; i + 2 < nx; ++i)
          add_distance(model, id(i, j), id(i + 2, j), spec.bending_params, bending);
      for (int j = 0; j + 2 < ny; ++j)
        for (int i = 0; i < nx; ++i)
          add_distance(model, id(i, j), id(i, j + 2), spec.bending_params, bending);
    }
  }
  return {begin, begin + n};
}

ParticleRange add_tet_block(Model& model, const TetBlockSpec& spec) {
  for (int a = 0; a < 3; ++a)
    require_min("TetBlockSpec.cells[" + std::to_string(a) + "]", spec.cells[static_cast<size_t>(a)], 1);
  for (int a = 0; a < 3; ++a)
    require_positive("TetBlockSpec.size[" + std::to_string(a) + "]", spec.size[a]);
  require_finite("TetBlockSpec.origin", spec.origin);
  require_positive("TetBlockSpec.density", spec.density);
  require_positive("TetBlockSpec.radius", spec.radius);
  if (spec.tets_per_cell != 5 && spec.tets_per_cell != 6)
    throw std::invalid_argument("TetBlockSpec.tets_per_cell = " +
                                std::to_string(spec.tets_per_cell) + " is not one of 5, 6");
  require_params("TetBlockSpec.edge", spec.edge);
  require_params("TetBlockSpec.volume", spec.volume);

  const int cx = spec.cells[0], cy = spec.cells[1], cz = spec.cells[2];
  const int vx = cx + 1, vy = cy + 1, vz = cz + 1;
  TetMesh mesh;
  mesh.vertices.resize(vx * vy * vz, 3);
  auto vid = [&](int i, int j, int k) { return i + vx * (j + vy * k); };
  for (int k = 0; k < vz; ++k)
    for (int j = 0; j < vy; ++j)
      for (int i = 0; i < vx; ++i) {
        const Vec3 p = spec.origin + Vec3(spec.size.x() * i / cx, spec.size.y() * j / cy,
                                          spec.size.z() * k / cz);
        mesh.vertices.row(vid(i, j, k)) = p.transpose();
      }

  // Corner b = (bx, by, bz) in {0,1}^3 of cell (i, j, k) is encoded as bx + 2 by + 4 bz.
  // Six tets: the Kuhn split, one tet per path 000 -> 111 along the axes in the order of a
  // permutation; every cell is split the same way, so the face diagonals of neighbours agree.
  static constexpr std::array<std::array<int, 4>, 6> kKuhn{{
      {0, 1, 3, 7}, {0, 1, 5, 7}, {0, 2, 3, 7}, {0, 2, 6, 7}, {0, 4, 5, 7}, {0, 4, 6, 7}}};
  // Five tets: the central tet on the corners of even global parity i+j+k+bx+by+bz, and one tet
  // at each odd corner with its three neighbours. All cells put the face diagonals between the
  // even corners, so neighbours conform.
  static constexpr std::array<std::array<int, 4>, 5> kFiveEven{{
      {0, 3, 5, 6}, {1, 0, 3, 5}, {2, 0, 3, 6}, {4, 0, 5, 6}, {7, 3, 5, 6}}};
  static constexpr std::array<std::array<int, 4>, 5> kFiveOdd{{
      {1, 2, 4, 7}, {0, 1, 2, 4}, {3, 1, 2, 7}, {5, 1, 4, 7}, {6, 2, 4, 7}}};

  for (int k = 0; k < cz; ++k)
    for (int j = 0; j < cy; ++j)
      for (int i = 0; i < cx; ++i) {
        auto corner = [&](int b) { return vid(i + (b & 1), j + ((b >> 1) & 1), k + ((b >> 2) & 1)); };
        // Some of these local orderings are negative; add_tet_mesh (reorient) makes them positive.
        auto emit = [&](const std::array<int, 4>& local) {
          mesh.tets.push_back({corner(local[0]), corner(local[1]), corner(local[2]), corner(local[3])});
        };
        if (spec.tets_per_cell == 6) {
          for (const auto& local : kKuhn) emit(local);
        } else {
          const bool even = (i + j + k) % 2 == 0;
          for (const auto& local : even ? kFiveEven : kFiveOdd) emit(local);
        }
      }

  TetBodySpec body;
  body.density = spec.density;
  body.radius = spec.radius;
  body.reorient = true;
  body.edges = spec.edges;
  body.volumes = spec.volumes;
  body.edge = spec.edge;
  body.volume = spec.volume;
  return add_tet_mesh(model, mesh, body, "add_tet_block");
}

ParticleRange add_tri_block(Model& model, const TriBlockSpec& spec) {
  for (int a = 0; a < 2; ++a)
    require_min("TriBlockSpec.cells[" + std::to_string(a) + "]", spec.cells[static_cast<size_t>(a)], 1);
  for (int a = 0; a < 2; ++a)
    require_positive("TriBlockSpec.size[" + std::to_string(a) + "]", spec.size[static_cast<size_t>(a)]);
  require_finite("TriBlockSpec.origin", spec.origin);
  require_positive("TriBlockSpec.density", spec.density);
  require_positive("TriBlockSpec.thickness", spec.thickness);
  require_positive("TriBlockSpec.radius", spec.radius);
  require_params("TriBlockSpec.edge", spec.edge);

  const int cx = spec.cells[0], cy = spec.cells[1];
  const int vx = cx + 1, vy = cy + 1, n = vx * vy;
  Points x(n, 3);
  for (int j = 0; j < vy; ++j)
    for (int i = 0; i < vx; ++i)
      x.row(i + vx * j) =
          (spec.origin + Vec3(spec.size[0] * i / cx, spec.size[1] * j / cy, 0.0)).transpose();
  std::vector<std::array<int, 3>> local;
  local.reserve(static_cast<size_t>(2 * cx * cy));
  auto vid = [&](int i, int j) { return i + vx * j; };
  for (int j = 0; j < cy; ++j)
    for (int i = 0; i < cx; ++i) {
      const int a = vid(i, j), b = vid(i + 1, j), c = vid(i + 1, j + 1), d = vid(i, j + 1);
      if ((i + j) % 2 == 0) {  // diagonal a-c
        local.push_back({a, b, c});
        local.push_back({a, c, d});
      } else {  // diagonal b-d
        local.push_back({a, b, d});
        local.push_back({b, c, d});
      }
    }
  std::vector<double> masses(static_cast<size_t>(n), 0.0);
  for (const auto& t : local) {
    const Vec3 e1 = Vec3(x.row(t[1]) - x.row(t[0])), e2 = Vec3(x.row(t[2]) - x.row(t[0]));
    const double m = spec.density * spec.thickness * 0.5 * e1.cross(e2).norm() / 3.0;
    for (int v : t) masses[static_cast<size_t>(v)] += m;
  }
  const int begin = append_particles(model, x, masses, spec.radius);
  std::vector<std::array<int, 2>> edges;
  for (const auto& t : local) {
    model.triangles.push_back({begin + t[0], begin + t[1], begin + t[2]});
    for (int k = 0; k < 3; ++k) {
      const int p = t[static_cast<size_t>(k)], q = t[static_cast<size_t>((k + 1) % 3)];
      edges.push_back({std::min(p, q), std::max(p, q)});
    }
  }
  std::sort(edges.begin(), edges.end());
  edges.erase(std::unique(edges.begin(), edges.end()), edges.end());
  const std::uint16_t group = spec.edges ? model.group_index("edge") : 0;
  for (const auto& e : edges) {
    model.edges.push_back({begin + e[0], begin + e[1]});
    if (spec.edges) add_distance(model, begin + e[0], begin + e[1], spec.edge, group);
  }
  model.surface_closed = false;
  return {begin, begin + n};
}

namespace {

// A uniform double in [0, 1) from the top 53 bits of one 64-bit draw: the same on every
// platform (std::uniform_real_distribution is implementation-defined).
double uniform01(std::mt19937_64& rng) {
  return static_cast<double>(rng() >> 11) * 0x1.0p-53;
}

// The ring layout of add_packed_spheres (its common fields already checked).
ParticleRange add_ring_spheres(Model& model, const PackedSpheresSpec& spec) {
  if (spec.count[1] != 1 || spec.count[2] != 1)
    throw std::invalid_argument("PackedSpheresSpec.count = [" + std::to_string(spec.count[0]) +
                                ", " + std::to_string(spec.count[1]) + ", " +
                                std::to_string(spec.count[2]) +
                                "]: the ring layout takes count[0] spheres, count[1] and count[2] "
                                "must be 1");
  require_positive("PackedSpheresSpec.ring_radius", spec.ring_radius);
  require_finite("PackedSpheresSpec.up", spec.up);
  if (!(spec.up.norm() > 0.0)) throw std::invalid_argument("PackedSpheresSpec.up must be non-zero");
  const Vec3 up = spec.up.normalized();
  Vec3 e1 = Vec3::UnitX() - Vec3::UnitX().dot(up) * up;
  if (e1.norm() < 1e-9) e1 = Vec3::UnitZ() - Vec3::UnitZ().dot(up) * up;  // up along x
  e1.normalize();
  const Vec3 e2 = up.cross(e1);
  const int n = spec.count[0];
  Points x(n, 3);
  std::mt19937_64 rng(spec.seed);
  for (int k = 0; k < n; ++k) {
    const double a = 2.0 * std::numbers::pi * k / n;
    Vec3 p = spec.origin + spec.ring_radius * (std::cos(a) * e1 + std::sin(a) * e2);
    for (int i = 0; i < 3; ++i) p[i] += spec.jitter * (2.0 * uniform01(rng) - 1.0);
    x.row(k) = p.transpose();
  }
  const int begin =
      append_particles(model, x, std::vector<double>(static_cast<size_t>(n), spec.mass), spec.radius);
  return {begin, begin + n};
}

}  // namespace

ParticleRange add_packed_spheres(Model& model, const PackedSpheresSpec& spec) {
  for (int a = 0; a < 3; ++a)
    require_min("PackedSpheresSpec.count[" + std::to_string(a) + "]", spec.count[static_cast<size_t>(a)], 1);
  require_positive("PackedSpheresSpec.radius", spec.radius);
  require_non_negative("PackedSpheresSpec.gap", spec.gap);
  require_finite("PackedSpheresSpec.origin", spec.origin);
  require_positive("PackedSpheresSpec.mass", spec.mass);
  require_non_negative("PackedSpheresSpec.jitter", spec.jitter);
  if (spec.layout == SpheresLayout::Ring) return add_ring_spheres(model, spec);
  const double spacing = 2.0 * spec.radius * (1.0 + spec.gap);
  // Two neighbours along an axis come closest when each moves `jitter` towards the other.
  if (!(spacing > 2.0 * spec.radius + 2.0 * spec.jitter))
    throw std::invalid_argument("PackedSpheresSpec.jitter = " +
                                format_number(spec.jitter, kExactDigits) +
                                " must be below radius * gap = " +
                                format_number(spec.radius * spec.gap, kExactDigits) +
                                " so that the spheres cannot overlap");

  const int nx = spec.count[0], ny = spec.count[1], nz = spec.count[2];
  const int n = nx * ny * nz;
  Points x(n, 3);
  std::mt19937_64 rng(spec.seed);
  for (int k = 0; k < nz; ++k)
    for (int j = 0; j < ny; ++j)
      for (int i = 0; i < nx; ++i) {
        Vec3 p = spec.origin + spacing * Vec3(i, j, k);
        for (int a = 0; a < 3; ++a) p[a] += spec.jitter * (2.0 * uniform01(rng) - 1.0);
        x.row(i + nx * (j + ny * k)) = p.transpose();
      }
  const int begin =
      append_particles(model, x, std::vector<double>(static_cast<size_t>(n), spec.mass), spec.radius);
  return {begin, begin + n};
}

}  // namespace pbdbench
