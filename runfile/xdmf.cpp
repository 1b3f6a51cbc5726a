#include "runfile/xdmf.hpp"

#include <H5Cpp.h>
#include <fmt/format.h>

#include <algorithm>
#include <array>
#include <cmath>
#include <fstream>
#include <limits>
#include <map>
#include <numbers>
#include <sstream>
#include <string>
#include <vector>

#include "core/constraint_functions.hpp"
#include "metrics/metrics.hpp"
#include "runfile/output_guard.hpp"
#include "runfile/frame_reader.hpp"
#include "runfile/run_file.hpp"

namespace pbdbench {

namespace fs = std::filesystem;

namespace {

constexpr double kNaN = std::numeric_limits<double>::quiet_NaN();
constexpr const char* kMarker = "<!-- pbdbench export: ";

[[noreturn]] void fail(const fs::path& path, const std::string& what) {
  throw std::runtime_error(path.string() + ": " + what);
}

// A triangle mesh (collider geometry).
struct Mesh {
  std::vector<Vec3> points;
  std::vector<std::array<int, 3>> triangles;
};

Mesh plane_quad(const PlaneCollider& p, const Vec3& around, double half) {
  const double nn = p.normal.norm();
  const Vec3 n = p.normal / nn;
  const double offset = p.offset / nn;
  const Vec3 c = around - (n.dot(around) + offset) * n;  // `around` projected onto the plane
  Vec3 u = std::abs(n.x()) < 0.9 ? Vec3::UnitX() : Vec3::UnitY();
  u = (u - u.dot(n) * n).normalized();
  const Vec3 v = n.cross(u);
  Mesh m;
  m.points = {c - half * u - half * v, c + half * u - half * v, c + half * u + half * v, c - half * u + half * v};
  m.triangles = {{0, 1, 2}, {0, 2, 3}};
  return m;
}

// A UV sphere; for a bowl only the half below the centre (along -up).
Mesh sphere_mesh(const Vec3& c, double r, bool bowl, const Vec3& up) {
  const int rings = 12, segments = 24;
  Vec3 a = std::abs(up.x()) < 0.9 ? Vec3::UnitX() : Vec3::UnitY();
  a = (a - a.dot(up) * up).normalized();
  const Vec3 b = up.cross(a);
  Mesh m;
  const int first_ring = bowl ? rings / 2 : 0;  // polar angle from +up: bowl keeps the lower half
  for (int i = first_ring; i <= rings; ++i) {
    const double theta = std::numbers::pi * i / rings;
    for (int j = 0; j < segments; ++j) {
      const double phi = 2.0 * std::numbers::pi * j / segments;
      m.points.push_back(c + r * (std::cos(theta) * up + std::sin(theta) * (std::cos(phi) * a + std::sin(phi) * b)));
    }
  }
  const int ring_count = rings - first_ring;
  for (int i = 0; i < ring_count; ++i)
    for (int j = 0; j < segments; ++j) {
      const int p0 = i * segments + j, p1 = i * segments + (j + 1) % segments;
      const int q0 = p0 + segments, q1 = p1 + segments;
      m.triangles.push_back({p0, q0, q1});
      m.triangles.push_back({p0, q1, p1});
    }
  return m;
}

// Every collider at time t as one mesh.
Mesh collider_mesh(const Model& model, double t, const Vec3& around, double half) {
  Mesh all;
  auto add = [&](const Mesh& m) {
    const int base = static_cast<int>(all.points.size());
    all.points.insert(all.points.end(), m.points.begin(), m.points.end());
    for (auto tri : m.triangles) all.triangles.push_back({tri[0] + base, tri[1] + base, tri[2] + base});
  };
  for (const PlaneCollider& p : model.planes)
    if (p.normal.norm() > 0.0) add(plane_quad(p, around, half));
  const Vec3 up = up_direction(model);
  for (const SphereCollider& s : model.spheres)
    add(sphere_mesh(sphere_center(model, s, t), s.radius, s.side == SphereSide::Bowl, up));
  for (const MeshCollider& mc : model.meshes) {
    Mesh m;
    const Vec3 offset = mesh_offset(model, mc, t);
    for (Eigen::Index i = 0; i < mc.vertices.rows(); ++i)
      m.points.push_back(Vec3(mc.vertices.row(i).transpose()) + offset);
    for (const auto& tri : mc.triangles) m.triangles.push_back({tri[0], tri[1], tri[2]});
    add(m);
  }
  return all;
}

template <size_t K>
std::array<int, K> sorted(std::array<int, K> a) {
  std::sort(a.begin(), a.end());
  return a;
}

// The cells of one topology, each once whatever the order of its particles.
template <size_t K>
struct Cells {
  std::vector<std::array<int, K>> cells;
  std::map<std::array<int, K>, int> index;  // sorted particles -> cell
  void add(const std::array<int, K>& c) {
    if (index.emplace(sorted(c), static_cast<int>(cells.size())).second) cells.push_back(c);
  }
};

// A constraint's particles (an FEM constraint's are its element's), sorted; empty past arity 4.
std::vector<int> constraint_particles(const Model& model, const Constraint& c) {
  std::vector<int> p;
  int count = arity(c.kind);
  if (is_fem_kind(c.kind) && c.element >= 0 && c.element < static_cast<int>(model.elements.size())) {
    const FemElement& e = model.elements[static_cast<size_t>(c.element)];
    count = e.vertices;
    for (int k = 0; k < count && k < 4; ++k) p.push_back(e.particles[static_cast<size_t>(k)]);
  } else {
    for (int k = 0; k < count && k < 4; ++k) p.push_back(c.particles[static_cast<size_t>(k)]);
  }
  std::sort(p.begin(), p.end());
  return p;
}

// A dataset of doubles; `compress`: one chunk, shuffled and deflated at level 1 (the standard
// filters: ParaView, h5py and meshio read them).
void write_dataset(H5::H5File& f, const std::string& name, const std::vector<hsize_t>& dims,
                   const double* data, bool compress = false) {
  H5::DataSpace space(static_cast<int>(dims.size()), dims.data());
  H5::DSetCreatPropList plist;
  bool empty = false;
  for (hsize_t d : dims) empty = empty || d == 0;
  if (compress && !empty) {
    plist.setChunk(static_cast<int>(dims.size()), dims.data());
    plist.setShuffle();
    plist.setDeflate(1);
  }
  H5::DataSet ds = f.createDataSet(name, H5::PredType::IEEE_F64LE, space, plist);
  hsize_t n = 1;
  for (hsize_t d : dims) n *= d;
  if (n > 0) ds.write(data, H5::PredType::NATIVE_DOUBLE);
}

void write_ints(H5::H5File& f, const std::string& name, const std::vector<hsize_t>& dims, const int* data) {
  H5::DataSpace space(static_cast<int>(dims.size()), dims.data());
  H5::DataSet ds = f.createDataSet(name, H5::PredType::STD_I32LE, space);
  hsize_t n = 1;
  for (hsize_t d : dims) n *= d;
  if (n > 0) ds.write(data, H5::PredType::NATIVE_INT);
}

std::string dims_text(const std::vector<hsize_t>& d) {
  std::string s;
  for (hsize_t x : d) {
    if (!s.empty()) s += ' ';
    s += std::to_string(x);
  }
  return s;
}

// A DataItem reading a whole dataset (XDMF readers such as meshio's take no hyperslab).
std::string whole_item(const std::string& file_and_path, const std::vector<hsize_t>& dims, bool ints = false) {
  return fmt::format("<DataItem Dimensions=\"{}\" NumberType=\"{}\" Precision=\"{}\" Format=\"HDF\">{}</DataItem>",
                     dims_text(dims), ints ? "Int" : "Float", ints ? 4 : 8, file_and_path);
}

bool is_our_export(const fs::path& p) {
  std::ifstream in(p);
  std::string line;
  for (int k = 0; k < 3 && std::getline(in, line); ++k)
    if (line.find(kMarker) != std::string::npos) return true;
  return false;
}

bool is_our_data(const fs::path& p) {
  try {
    H5::H5File f(p.string(), H5F_ACC_RDONLY);
    return f.attrExists("pbdbench_viz");
  } catch (const H5::Exception&) {
    return false;
  }
}

// Only an earlier export of ours is replaced, never the run file exported (output_guard.hpp).
void check_replace(const fs::path& p, const std::string& argument, const std::string& kind,
                   bool (*ours)(const fs::path&), const fs::path& run_file) {
  check_output(p, OutputTarget{argument, kind, ours, {{run_file, "the run file exported"}}});
}

}  // namespace

bool is_xdmf_data(const fs::path& path) {
  std::error_code ec;
  if (!fs::is_regular_file(path, ec)) return false;
  H5::Exception::dontPrint();
  return is_our_data(path);
}

fs::path default_xdmf_path(const fs::path& run_file) {
  fs::path p = run_file;
  p.replace_extension(".xdmf");
  return p;
}

XdmfSummary write_xdmf(const fs::path& run_file, const Model& model, const fs::path& xdmf,
                       const std::string& argument) {
  H5::Exception::dontPrint();
  XdmfSummary out;
  out.xdmf = xdmf;
  out.data = xdmf;
  out.data.replace_extension(".viz.h5");
  check_replace(xdmf, argument, "ParaView export", is_our_export, run_file);
  check_replace(out.data, argument, "ParaView data file", is_our_data, run_file);
  claim_temporary(xdmf, argument);  // both temporaries before anything is written
  claim_temporary(out.data, argument);

  // The run's frames, through the run file's reader (run_file.hpp): here their times and the last
  // frame (its particle count checked before anything is written); below one frame at a time
  // (frame_reader.hpp), so that the export's memory does not grow with the run's length.
  const int n = model.particle_count();
  RunFileParts parts;
  parts.series = false;
  parts.frames = RunFileParts::Frames::Last;
  parts.velocities = true;  // copied per frame: a reader of the XDMF needs no hyperslab
  const RunFileData run_data = read_run_file(run_file, parts);
  const std::vector<double>& times = run_data.frame_time;
  if (times.empty() || run_data.frames.size() != 1) fail(run_file, "has no frames");
  const auto check_frame = [&](const Points& frame) {
    if (frame.rows() != n)
      fail(run_file, fmt::format("frames of {} particles, the scene has {}: not this scene's run file",
                                 frame.rows(), n));
  };
  check_frame(run_data.frames.back());
  const bool velocities = run_data.has_velocities && run_data.velocities.size() == 1;
  const hsize_t F = times.size();
  out.frames = static_cast<long>(F);

  // Topology.
  Cells<2> edges;
  Cells<3> tris;
  Cells<4> tets;
  for (const auto& e : model.edges) edges.add(e);
  for (const Constraint& c : model.constraints)
    if (c.kind == ConstraintKind::Distance) edges.add({c.particles[0], c.particles[1]});
  for (const auto& t : model.triangles) tris.add(t);
  for (const auto& t : model.tets) tets.add(t);
  const size_t E = edges.cells.size(), T = tris.cells.size(), K = tets.cells.size();
  out.edges = static_cast<long>(E);
  out.triangles = static_cast<long>(T);
  out.tets = static_cast<long>(K);

  // What each cell's constraint_error is made of: the constraints whose particles all belong to
  // the cell (a cloth triangle: the distance constraints of its edges; a tet: its volume or FEM
  // constraint and those of its edges and faces); for a cell that holds no whole constraint (a
  // tet mesh's surface triangle), the constraints that share a particle with it. A cell that no
  // constraint touches has error 0: nothing on it can be violated. The field so has a value on
  // every cell it colours, NaN only where a constraint's own error is NaN (a run that exploded).
  // Cells are numbered tets, then triangles, then edges: the order of the mixed topology below.
  const size_t C = K + T + E;
  std::vector<std::vector<int>> cell_particles(C);
  for (size_t t = 0; t < K; ++t) cell_particles[t].assign(tets.cells[t].begin(), tets.cells[t].end());
  for (size_t t = 0; t < T; ++t) cell_particles[K + t].assign(tris.cells[t].begin(), tris.cells[t].end());
  for (size_t e = 0; e < E; ++e) cell_particles[K + T + e].assign(edges.cells[e].begin(), edges.cells[e].end());
  std::map<std::vector<int>, std::vector<int>> holders;  // sorted particle subset -> cells holding it
  for (size_t c = 0; c < C; ++c) {
    std::vector<int> s = cell_particles[c];
    std::sort(s.begin(), s.end());
    const unsigned size = static_cast<unsigned>(s.size());
    for (unsigned mask = 1; mask < (1u << size); ++mask) {
      std::vector<int> sub;
      for (unsigned k = 0; k < size; ++k)
        if (mask & (1u << k)) sub.push_back(s[k]);
      if (sub.size() >= 2) holders[sub].push_back(static_cast<int>(c));
    }
  }
  std::vector<std::vector<int>> whole(C);                   // per cell: the constraints inside it
  std::vector<std::vector<int>> on_particle(static_cast<size_t>(n));  // per particle: its constraints
  for (size_t j = 0; j < model.constraints.size(); ++j) {
    const std::vector<int> p = constraint_particles(model, model.constraints[j]);
    for (int i : p)
      if (i >= 0 && i < n) on_particle[static_cast<size_t>(i)].push_back(static_cast<int>(j));
    if (p.size() < 2) continue;
    auto it = holders.find(p);
    if (it != holders.end())
      for (int c : it->second) whole[static_cast<size_t>(c)].push_back(static_cast<int>(j));
  }
  holders.clear();

  // Fields.
  const hsize_t N = static_cast<hsize_t>(n);
  std::vector<double> inv_mass(model.inv_mass), pinned(N);
  for (int i = 0; i < n; ++i) pinned[static_cast<size_t>(i)] = model.inv_mass[static_cast<size_t>(i)] == 0.0 ? 1.0 : 0.0;
  std::vector<double> change(C), cell_err(C);  // of one frame, all cells in the mixed order
  auto tri_area = [](const Vec3& a, const Vec3& b, const Vec3& c) { return 0.5 * (b - a).cross(c - a).norm(); };
  std::vector<double> err(model.constraints.size()), particle_err(static_cast<size_t>(n));
  // The cell fields of the frame at x, into change and cell_err.
  const auto cell_fields = [&](const Points& x) {
    for (size_t j = 0; j < err.size(); ++j) err[j] = constraint_error(model, model.constraints[j], x);
    auto worst = [&](const std::vector<int>& cs) {
      double w = 0.0;
      for (int j : cs) {
        const double e = err[static_cast<size_t>(j)];
        if (std::isnan(e)) return kNaN;
        w = std::max(w, e);
      }
      return w;
    };
    for (int i = 0; i < n; ++i) particle_err[static_cast<size_t>(i)] = worst(on_particle[static_cast<size_t>(i)]);
    for (size_t c = 0; c < C; ++c) {
      double w = 0.0;
      if (!whole[c].empty()) {
        w = worst(whole[c]);
      } else {
        for (int i : cell_particles[c]) {
          const double e = particle_err[static_cast<size_t>(i)];
          if (std::isnan(e)) {
            w = kNaN;
            break;
          }
          w = std::max(w, e);
        }
      }
      cell_err[c] = w;
    }
    const Points& X = model.rest_positions;
    for (size_t t = 0; t < K; ++t) {
      const auto [a, b, c, d] = tets.cells[t];
      const double v0 = tet_signed_volume(X.row(a), X.row(b), X.row(c), X.row(d));
      change[t] = v0 != 0.0 ? tet_signed_volume(x.row(a), x.row(b), x.row(c), x.row(d)) / v0 - 1.0 : kNaN;
    }
    for (size_t t = 0; t < T; ++t) {
      const auto [a, b, c] = tris.cells[t];
      const double a0 = tri_area(X.row(a), X.row(b), X.row(c));
      change[K + t] = a0 > 0.0 ? tri_area(x.row(a), x.row(b), x.row(c)) / a0 - 1.0 : kNaN;
    }
    for (size_t e = 0; e < E; ++e) {
      const auto [a, b] = edges.cells[e];
      const double l0 = (X.row(a) - X.row(b)).norm();
      change[K + T + e] = l0 > 0.0 ? (x.row(a) - x.row(b)).norm() / l0 - 1.0 : kNaN;
    }
  };

  // The mixed topology: per cell its XDMF type (6 tetrahedron, 4 triangle, 2 polyline with its
  // node count) and particles.
  std::vector<int> mixed;
  mixed.reserve(5 * K + 4 * T + 4 * E);
  for (const auto& t : tets.cells) mixed.insert(mixed.end(), {6, t[0], t[1], t[2], t[3]});
  for (const auto& t : tris.cells) mixed.insert(mixed.end(), {4, t[0], t[1], t[2]});
  for (const auto& e : edges.cells) mixed.insert(mixed.end(), {2, 2, e[0], e[1]});

  // Colliders: planes as quads around the body's rest centroid, 2 x its extent (at least 1 m).
  Vec3 centroid = Vec3::Zero();
  double extent = 0.0;
  if (n > 0) {
    centroid = model.rest_positions.colwise().mean().transpose();
    for (int i = 0; i < n; ++i) extent = std::max(extent, (Vec3(model.rest_positions.row(i)) - centroid).norm());
  }
  const double half = std::max(2.0 * extent, 1.0);
  bool moving = false;
  for (const SphereCollider& s : model.spheres) moving = moving || s.motion >= 0;
  for (const MeshCollider& mc : model.meshes) moving = moving || mc.motion >= 0;
  // The colliders' triangles (the same in every frame), and their points at time t (moving, once
  // a frame; else once, at t = 0), made as the frames are written.
  std::vector<double> collider_points;
  std::vector<int> collider_tris;
  hsize_t CP = 0, CT = 0;
  const auto collider_frame = [&](double t) {
    const Mesh m = collider_mesh(model, t, centroid, half);
    CP = m.points.size();
    CT = m.triangles.size();
    collider_points.clear();
    for (const Vec3& p : m.points) collider_points.insert(collider_points.end(), {p.x(), p.y(), p.z()});
    return m;
  };
  for (const auto& t : collider_frame(0.0).triangles) collider_tris.insert(collider_tris.end(), t.begin(), t.end());
  out.collider_points = static_cast<long>(CP);

  // The data file: the topology, and per frame under /frames/NNNNNN/ what the XDMF reads, each
  // a whole dataset (scripts/runfile.py load_viz splits the cell fields by cell type again).
  const auto frame_group = [](hsize_t f) { return fmt::format("frames/{:06d}", f); };
  const std::string tmp = claim_temporary(out.data, argument).string();
  try {
    H5::H5File h(tmp, H5F_ACC_EXCL);  // afresh: never through a link planted at the temporary
    {
      const H5::StrType st(H5::PredType::C_S1, H5T_VARIABLE);
      H5::Attribute a = h.createAttribute("pbdbench_viz", st, H5::DataSpace(H5S_SCALAR));
      a.write(st, run_file.filename().string());
    }
    write_dataset(h, "inv_mass", {N}, inv_mass.data());
    write_dataset(h, "pinned", {N}, pinned.data());
    std::vector<int> flat;
    for (auto& e : edges.cells) flat.insert(flat.end(), e.begin(), e.end());
    write_ints(h, "edges", {E, 2}, flat.data());
    flat.clear();
    for (auto& t : tris.cells) flat.insert(flat.end(), t.begin(), t.end());
    write_ints(h, "triangles", {T, 3}, flat.data());
    flat.clear();
    for (auto& t : tets.cells) flat.insert(flat.end(), t.begin(), t.end());
    write_ints(h, "tets", {K, 4}, flat.data());
    write_ints(h, "mixed", {static_cast<hsize_t>(mixed.size())}, mixed.data());
    write_ints(h, "collider_triangles", {CT, 3}, collider_tris.data());
    h.createGroup("frames");
    std::vector<double> buffer(N * 3);
    const std::vector<double> read_times = for_each_frame(run_file, velocities, [&](size_t f, double t, const Points& x,
                                                                                    const Points* v) {
      if (f >= F) fail(run_file, "more frames than frame times");
      check_frame(x);
      cell_fields(x);
      const std::string g = frame_group(f);
      h.createGroup(g);
      for (int i = 0; i < n; ++i)
        for (int k = 0; k < 3; ++k) buffer[static_cast<size_t>(i) * 3 + static_cast<size_t>(k)] = x(i, k);
      write_dataset(h, g + "/positions", {N, 3}, buffer.data(), true);
      for (int i = 0; i < n; ++i)
        for (int k = 0; k < 3; ++k)
          buffer[static_cast<size_t>(i) * 3 + static_cast<size_t>(k)] = x(i, k) - model.rest_positions(i, k);
      write_dataset(h, g + "/displacement", {N, 3}, buffer.data(), true);
      if (velocities && v != nullptr) {
        for (int i = 0; i < n; ++i)
          for (int k = 0; k < 3; ++k) buffer[static_cast<size_t>(i) * 3 + static_cast<size_t>(k)] = (*v)(i, k);
        write_dataset(h, g + "/velocity", {N, 3}, buffer.data(), true);
      }
      write_dataset(h, g + "/change", {C}, change.data(), true);
      write_dataset(h, g + "/constraint_error", {C}, cell_err.data(), true);
      if (moving || f == 0) {
        if (moving) collider_frame(t);
        write_dataset(h, g + "/collider_points", {CP, 3}, collider_points.data(), true);
      }
    });
    if (read_times.size() != F) fail(run_file, "its frames changed while they were exported");
  } catch (const H5::Exception& e) {
    fail(out.data, "cannot write: " + e.getDetailMsg());
  }
  fs::rename(tmp, out.data);

  // The XDMF (version 3: ParaView's readers, old and new, and meshio's TimeSeriesReader read it).
  // Two temporal collections: the colliders, then the body, one uniform grid a frame with the
  // mixed topology. meshio reads the last collection; every DataItem is a whole dataset.
  const std::string data = out.data.filename().string();
  auto item = [&](const std::string& path, const std::vector<hsize_t>& dims, bool ints = false) {
    return whole_item(data + ":/" + path, dims, ints);
  };
  std::ostringstream x;
  x << "<?xml version=\"1.0\" ?>\n" << kMarker << run_file.filename().string() << " -->\n"
    << "<Xdmf Version=\"3.0\">\n<Domain>\n";
  if (CP > 0 && CT > 0) {
    x << "<Grid Name=\"colliders\" GridType=\"Collection\" CollectionType=\"Temporal\">\n";
    for (hsize_t f = 0; f < F; ++f) {
      x << fmt::format("<Grid Name=\"colliders {}\" GridType=\"Uniform\">\n<Time Value=\"{:.17g}\"/>\n", f, times[f]);
      x << fmt::format("<Topology TopologyType=\"Triangle\" NumberOfElements=\"{}\">{}</Topology>\n", CT,
                       item("collider_triangles", {CT, 3}, true));
      x << "<Geometry GeometryType=\"XYZ\">" << item(frame_group(moving ? f : 0) + "/collider_points", {CP, 3})
        << "</Geometry>\n</Grid>\n";
    }
    x << "</Grid>\n";
  }
  x << "<Grid Name=\"body\" GridType=\"Collection\" CollectionType=\"Temporal\">\n";
  for (hsize_t f = 0; f < F; ++f) {
    const std::string g = frame_group(f);
    x << fmt::format("<Grid Name=\"frame {}\" GridType=\"Uniform\">\n<Time Value=\"{:.17g}\"/>\n", f, times[f]);
    x << fmt::format("<Topology TopologyType=\"Mixed\" NumberOfElements=\"{}\">{}</Topology>\n", C,
                     item("mixed", {static_cast<hsize_t>(mixed.size())}, true));
    x << "<Geometry GeometryType=\"XYZ\">" << item(g + "/positions", {N, 3}) << "</Geometry>\n";
    if (velocities)
      x << "<Attribute Name=\"velocity\" AttributeType=\"Vector\" Center=\"Node\">" << item(g + "/velocity", {N, 3})
        << "</Attribute>\n";
    x << "<Attribute Name=\"displacement\" AttributeType=\"Vector\" Center=\"Node\">" << item(g + "/displacement", {N, 3})
      << "</Attribute>\n";
    x << "<Attribute Name=\"inv_mass\" AttributeType=\"Scalar\" Center=\"Node\">" << item("inv_mass", {N})
      << "</Attribute>\n";
    x << "<Attribute Name=\"pinned\" AttributeType=\"Scalar\" Center=\"Node\">" << item("pinned", {N}) << "</Attribute>\n";
    if (C > 0) {
      x << "<Attribute Name=\"change\" AttributeType=\"Scalar\" Center=\"Cell\">" << item(g + "/change", {C})
        << "</Attribute>\n";
      x << "<Attribute Name=\"constraint_error\" AttributeType=\"Scalar\" Center=\"Cell\">"
        << item(g + "/constraint_error", {C}) << "</Attribute>\n";
    }
    x << "</Grid>\n";
  }
  x << "</Grid>\n</Domain>\n</Xdmf>\n";
  write_text_output(xdmf, x.str(), argument);
  return out;
}

}  // namespace pbdbench
