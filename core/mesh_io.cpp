// Mesh import (core/mesh_io.hpp): Wavefront OBJ, TetGen .node/.ele, Gmsh ASCII 2.2 and 4.1, and
// the bodies built from them. Readers work line by line so that every error names its line.
#include "core/mesh_io.hpp"

#include <algorithm>
#include <cctype>
#include <charconv>
#include <cmath>
#include <fstream>
#include <map>
#include <numeric>
#include <stdexcept>
#include <string_view>
#include <tuple>
#include <unordered_map>
#include <utility>

#include "core/build_helpers.hpp"
#include "core/constraint_functions.hpp"

namespace pbdbench {

using namespace core::detail;  // core/build_helpers.hpp

namespace {

std::string error_message(const std::string& file, int line, const std::string& what) {
  if (line > 0) return file + ":" + std::to_string(line) + ": " + what;
  return file + ": " + what;
}

}  // namespace

MeshError::MeshError(const std::string& file, int line, const std::string& what)
    : std::runtime_error(error_message(file, line, what)), file_(file), line_(line) {}

namespace {

// ---------------------------------------------------------------------------------------------
// Line reading and number parsing.

struct Line {
  int number = 0;                       // 1-based line number in the file
  std::vector<std::string_view> words;  // whitespace-separated, comment stripped
};

// The file's text, one string per line (CR stripped). Throws MeshError when it cannot be read.
std::vector<std::string> read_lines(const std::string& path) {
  std::ifstream in(path);
  if (!in) throw MeshError(path, 0, "cannot open the file");
  std::vector<std::string> lines;
  std::string s;
  while (std::getline(in, s)) {
    if (!s.empty() && s.back() == '\r') s.pop_back();
    lines.push_back(std::move(s));
  }
  return lines;
}

// Splits a line into words after removing everything from `comment` on (0: no comments).
std::vector<std::string_view> split_words(std::string_view text, char comment) {
  if (comment != 0) {
    const size_t c = text.find(comment);
    if (c != std::string_view::npos) text = text.substr(0, c);
  }
  std::vector<std::string_view> words;
  size_t i = 0;
  while (i < text.size()) {
    while (i < text.size() && std::isspace(static_cast<unsigned char>(text[i]))) ++i;
    size_t j = i;
    while (j < text.size() && !std::isspace(static_cast<unsigned char>(text[j]))) ++j;
    if (j > i) words.push_back(text.substr(i, j - i));
    i = j;
  }
  return words;
}

// The non-blank lines of a file, split into words, comments removed.
class LineReader {
 public:
  LineReader(std::string path, char comment) : path_(std::move(path)), text_(read_lines(path_)) {
    for (size_t i = 0; i < text_.size(); ++i) {
      Line l{static_cast<int>(i) + 1, split_words(text_[i], comment)};
      if (!l.words.empty()) lines_.push_back(std::move(l));
    }
  }
  const std::string& path() const { return path_; }
  bool done() const { return next_ >= lines_.size(); }
  // The next non-blank line; `what` says what was expected when the file ends early.
  const Line& next(const std::string& what) {
    if (done()) throw MeshError(path_, static_cast<int>(text_.size()), "file ends before " + what);
    return lines_[next_++];
  }
  const std::vector<Line>& all() const { return lines_; }

 private:
  std::string path_;
  std::vector<std::string> text_;
  std::vector<Line> lines_;
  size_t next_ = 0;
};

double parse_double(const std::string& file, int line, std::string_view word, const char* what) {
  double v = 0.0;
  const char* first = word.data();
  const char* last = word.data() + word.size();
  if (!word.empty() && *first == '+') ++first;  // from_chars does not take a leading '+'
  const auto r = std::from_chars(first, last, v);
  if (r.ec != std::errc() || r.ptr != last)
    throw MeshError(file, line, std::string("cannot read ") + what + " '" + std::string(word) + "'");
  if (!std::isfinite(v))
    throw MeshError(file, line, std::string(what) + " '" + std::string(word) + "' is not finite");
  return v;
}

long long parse_int(const std::string& file, int line, std::string_view word, const char* what) {
  long long v = 0;
  const char* first = word.data();
  const char* last = word.data() + word.size();
  if (!word.empty() && *first == '+') ++first;
  const auto r = std::from_chars(first, last, v);
  if (r.ec != std::errc() || r.ptr != last)
    throw MeshError(file, line, std::string("cannot read ") + what + " '" + std::string(word) + "'");
  return v;
}

// A count (>= 0) that fits an int.
int parse_count(const std::string& file, int line, std::string_view word, const char* what) {
  const long long v = parse_int(file, line, word, what);
  if (v < 0 || v > 1'000'000'000)
    throw MeshError(file, line, std::string(what) + " " + std::to_string(v) + " is out of range");
  return static_cast<int>(v);
}

void expect_words(const std::string& file, const Line& l, size_t count, const char* what) {
  if (l.words.size() != count)
    throw MeshError(file, l.number, std::string(what) + ": expected " + std::to_string(count) +
                                        " values, found " + std::to_string(l.words.size()));
}

std::string lower_extension(const std::string& path) {
  const size_t dot = path.find_last_of('.');
  const size_t slash = path.find_last_of('/');
  if (dot == std::string::npos || (slash != std::string::npos && dot < slash)) return "";
  std::string ext = path.substr(dot);
  for (char& c : ext) c = static_cast<char>(std::tolower(static_cast<unsigned char>(c)));
  return ext;
}

}  // namespace

// ---------------------------------------------------------------------------------------------
// Wavefront OBJ.

SurfaceMesh read_obj(const std::string& path) {
  LineReader reader(path, '#');
  std::vector<Vec3> vertices;
  struct Face {
    std::vector<long long> refs;  // 1-based, resolved from negative indices
    int line;
  };
  std::vector<Face> faces;
  for (const Line& l : reader.all()) {
    const std::string_view key = l.words[0];
    if (key == "v") {
      // x y z, optionally w or a colour r g b after them.
      if (l.words.size() < 4)
        throw MeshError(path, l.number, "vertex: expected at least 3 coordinates, found " +
                                            std::to_string(l.words.size() - 1));
      Vec3 p;
      for (int a = 0; a < 3; ++a) p[a] = parse_double(path, l.number, l.words[1 + a], "coordinate");
      for (size_t w = 4; w < l.words.size(); ++w) parse_double(path, l.number, l.words[w], "value");
      vertices.push_back(p);
    } else if (key == "f") {
      if (l.words.size() < 4)
        throw MeshError(path, l.number, "face: expected at least 3 vertices, found " +
                                            std::to_string(l.words.size() - 1));
      Face f{{}, l.number};
      for (size_t w = 1; w < l.words.size(); ++w) {
        const std::string_view ref = l.words[w].substr(0, l.words[w].find('/'));
        long long idx = parse_int(path, l.number, ref, "vertex index");
        if (idx == 0) throw MeshError(path, l.number, "vertex index 0 (OBJ indices start at 1)");
        // A negative index counts back from the last vertex read so far.
        if (idx < 0) idx += static_cast<long long>(vertices.size()) + 1;
        if (idx < 1)
          throw MeshError(path, l.number, "vertex index " + std::string(ref) +
                                              " is out of range: only " +
                                              std::to_string(vertices.size()) + " vertices so far");
        f.refs.push_back(idx);
      }
      faces.push_back(std::move(f));
    }
    // Everything else (vt, vn, o, g, s, usemtl, mtllib, l, ...) is ignored.
  }

  SurfaceMesh mesh;
  mesh.vertices.resize(static_cast<Eigen::Index>(vertices.size()), 3);
  for (size_t i = 0; i < vertices.size(); ++i)
    mesh.vertices.row(static_cast<Eigen::Index>(i)) = vertices[i].transpose();
  const long long n = static_cast<long long>(vertices.size());
  for (const Face& f : faces) {
    for (long long r : f.refs)
      if (r > n)
        throw MeshError(path, f.line, "vertex index " + std::to_string(r) +
                                          " is out of range: the file has " + std::to_string(n) +
                                          " vertices");
    for (size_t k = 1; k + 1 < f.refs.size(); ++k) {
      mesh.triangles.push_back({static_cast<int>(f.refs[0] - 1), static_cast<int>(f.refs[k] - 1),
                                static_cast<int>(f.refs[k + 1] - 1)});
      mesh.triangle_lines.push_back(f.line);
    }
  }
  return mesh;
}

// ---------------------------------------------------------------------------------------------
// TetGen .node / .ele.

TetMesh read_tetgen(const std::string& path) {
  std::string base = path;
  const std::string ext = lower_extension(path);
  if (ext == ".node" || ext == ".ele") base = path.substr(0, path.size() - ext.size());
  const std::string node_path = base + ".node", ele_path = base + ".ele";

  TetMesh mesh;
  long long first_index = 0;  // 0 or 1: the numbering of the .node file
  {
    LineReader r(node_path, '#');
    const Line& h = r.next("the header line");
    if (h.words.size() < 2 || h.words.size() > 4)
      throw MeshError(node_path, h.number, "header: expected 2 to 4 values (points, dimension, "
                                           "attributes, boundary markers), found " +
                                               std::to_string(h.words.size()));
    const int n = parse_count(node_path, h.number, h.words[0], "number of points");
    const int dim = parse_count(node_path, h.number, h.words[1], "dimension");
    if (dim != 3)
      throw MeshError(node_path, h.number, "dimension " + std::to_string(dim) + " is not supported (3 expected)");
    const int attributes = h.words.size() > 2 ? parse_count(node_path, h.number, h.words[2], "number of attributes") : 0;
    const int markers = h.words.size() > 3 ? parse_count(node_path, h.number, h.words[3], "boundary marker flag") : 0;
    if (markers > 1)
      throw MeshError(node_path, h.number, "boundary marker flag " + std::to_string(markers) + " is not 0 or 1");
    mesh.vertices.resize(n, 3);
    for (int i = 0; i < n; ++i) {
      const Line& l = r.next("point " + std::to_string(i + 1) + " of " + std::to_string(n));
      expect_words(node_path, l, static_cast<size_t>(4 + attributes + markers), "point");
      const long long index = parse_int(node_path, l.number, l.words[0], "point number");
      if (i == 0) {
        if (index != 0 && index != 1)
          throw MeshError(node_path, l.number, "the first point number is " + std::to_string(index) + ", not 0 or 1");
        first_index = index;
      } else if (index != first_index + i) {
        throw MeshError(node_path, l.number, "point number " + std::to_string(index) + ", expected " +
                                                 std::to_string(first_index + i));
      }
      for (int a = 0; a < 3; ++a)
        mesh.vertices(i, a) = parse_double(node_path, l.number, l.words[static_cast<size_t>(1 + a)], "coordinate");
      for (size_t w = 4; w < l.words.size(); ++w) parse_double(node_path, l.number, l.words[w], "attribute");
    }
    if (!r.done())
      throw MeshError(node_path, r.next("").number, "more points than the " + std::to_string(n) + " the header declares");
  }
  {
    LineReader r(ele_path, '#');
    const Line& h = r.next("the header line");
    if (h.words.size() < 2 || h.words.size() > 3)
      throw MeshError(ele_path, h.number, "header: expected 2 or 3 values (tetrahedra, nodes per "
                                          "tetrahedron, attributes), found " +
                                              std::to_string(h.words.size()));
    const int m = parse_count(ele_path, h.number, h.words[0], "number of tetrahedra");
    const int per = parse_count(ele_path, h.number, h.words[1], "nodes per tetrahedron");
    if (per != 4 && per != 10)
      throw MeshError(ele_path, h.number, "nodes per tetrahedron " + std::to_string(per) + " is not 4 or 10");
    const int attributes = h.words.size() > 2 ? parse_count(ele_path, h.number, h.words[2], "number of attributes") : 0;
    const long long n = mesh.vertices.rows();
    for (int e = 0; e < m; ++e) {
      const Line& l = r.next("tetrahedron " + std::to_string(e + 1) + " of " + std::to_string(m));
      expect_words(ele_path, l, static_cast<size_t>(1 + per + attributes), "tetrahedron");
      parse_int(ele_path, l.number, l.words[0], "tetrahedron number");
      std::array<int, 4> t{};
      for (int k = 0; k < 4; ++k) {  // the corners; the 6 edge nodes of a 10-node tet are dropped
        // Compared before subtracting: an index of INT64_MIN must not overflow.
        const long long given = parse_int(ele_path, l.number, l.words[static_cast<size_t>(1 + k)], "node index");
        const long long v = given < first_index ? -1 : given - first_index;
        if (v < 0 || v >= n)
          throw MeshError(ele_path, l.number, "node index " + std::string(l.words[static_cast<size_t>(1 + k)]) +
                                                  " is out of range [" + std::to_string(first_index) + ", " +
                                                  std::to_string(n + first_index) + ")");
        t[static_cast<size_t>(k)] = static_cast<int>(v);
      }
      for (size_t w = 5; w < l.words.size(); ++w) parse_double(ele_path, l.number, l.words[w], "value");
      mesh.tets.push_back(t);
    }
    if (!r.done())
      throw MeshError(ele_path, r.next("").number, "more tetrahedra than the " + std::to_string(m) + " the header declares");
  }
  return mesh;
}

// ---------------------------------------------------------------------------------------------
// Gmsh ASCII 2.2 and 4.1.

namespace {

// Skips lines up to and including `end` (e.g. "$EndNodes").
void skip_section(LineReader& r, const std::string& end) {
  while (true) {
    const Line& l = r.next("'" + end + "'");
    if (l.words[0] == end) return;
  }
}

void expect_end(LineReader& r, const std::string& end) {
  const Line& l = r.next("'" + end + "'");
  if (l.words.size() != 1 || l.words[0] != end)
    throw MeshError(r.path(), l.number, "expected '" + end + "', found '" + std::string(l.words[0]) + "'");
}

// Node tags to vertex indices.
using TagMap = std::unordered_map<long long, int>;

void add_node(TetMesh& mesh, TagMap& tags, const std::string& path, int line, long long tag, const Vec3& p) {
  if (!tags.emplace(tag, static_cast<int>(tags.size())).second)
    throw MeshError(path, line, "node tag " + std::to_string(tag) + " appears twice");
  const Eigen::Index i = mesh.vertices.rows();
  mesh.vertices.conservativeResize(i + 1, 3);
  mesh.vertices.row(i) = p.transpose();
}

int node_index(const TagMap& tags, const std::string& path, int line, std::string_view word) {
  const long long tag = parse_int(path, line, word, "node tag");
  const auto it = tags.find(tag);
  if (it == tags.end()) throw MeshError(path, line, "node tag " + std::to_string(tag) + " is not defined in $Nodes");
  return it->second;
}

// Number of nodes of the Gmsh element types a file may carry, for skipping; 0 when unknown.
int gmsh_nodes_of_type(long long type) {
  switch (type) {
    case 1: return 2;    // line
    case 2: return 3;    // triangle
    case 3: return 4;    // quadrangle
    case 4: return 4;    // tetrahedron
    case 5: return 8;    // hexahedron
    case 6: return 6;    // prism
    case 7: return 5;    // pyramid
    case 8: return 3;    // 3-node line
    case 9: return 6;    // 6-node triangle
    case 11: return 10;  // 10-node tetrahedron
    case 15: return 1;   // point
    default: return 0;
  }
}

void read_gmsh22_nodes(LineReader& r, TetMesh& mesh, TagMap& tags) {
  const std::string& path = r.path();
  const Line& h = r.next("the number of nodes");
  expect_words(path, h, 1, "$Nodes header");
  const int n = parse_count(path, h.number, h.words[0], "number of nodes");
  for (int i = 0; i < n; ++i) {
    const Line& l = r.next("node " + std::to_string(i + 1) + " of " + std::to_string(n));
    expect_words(path, l, 4, "node");
    Vec3 p;
    for (int a = 0; a < 3; ++a) p[a] = parse_double(path, l.number, l.words[static_cast<size_t>(1 + a)], "coordinate");
    add_node(mesh, tags, path, l.number, parse_int(path, l.number, l.words[0], "node tag"), p);
  }
  expect_end(r, "$EndNodes");
}

void read_gmsh22_elements(LineReader& r, TetMesh& mesh, const TagMap& tags) {
  const std::string& path = r.path();
  const Line& h = r.next("the number of elements");
  expect_words(path, h, 1, "$Elements header");
  const int m = parse_count(path, h.number, h.words[0], "number of elements");
  for (int e = 0; e < m; ++e) {
    // elm-number elm-type number-of-tags tag... node...
    const Line& l = r.next("element " + std::to_string(e + 1) + " of " + std::to_string(m));
    if (l.words.size() < 3)
      throw MeshError(path, l.number, "element: expected at least 3 values, found " + std::to_string(l.words.size()));
    parse_int(path, l.number, l.words[0], "element number");
    const long long type = parse_int(path, l.number, l.words[1], "element type");
    const int ntags = parse_count(path, l.number, l.words[2], "number of tags");
    const int nodes = gmsh_nodes_of_type(type);
    if (nodes > 0) expect_words(path, l, static_cast<size_t>(3 + ntags + nodes), "element");
    if (type != 4) continue;  // only 4-node tetrahedra are read
    std::array<int, 4> t{};
    for (int k = 0; k < 4; ++k)
      t[static_cast<size_t>(k)] = node_index(tags, path, l.number, l.words[static_cast<size_t>(3 + ntags + k)]);
    mesh.tets.push_back(t);
  }
  expect_end(r, "$EndElements");
}

void read_gmsh41_nodes(LineReader& r, TetMesh& mesh, TagMap& tags) {
  const std::string& path = r.path();
  // numEntityBlocks numNodes minNodeTag maxNodeTag
  const Line& h = r.next("the $Nodes header");
  expect_words(path, h, 4, "$Nodes header");
  const int blocks = parse_count(path, h.number, h.words[0], "number of entity blocks");
  const int total = parse_count(path, h.number, h.words[1], "number of nodes");
  for (int b = 0; b < blocks; ++b) {
    // entityDim entityTag parametric numNodesInBlock, then the tags, then the coordinates.
    const Line& bh = r.next("node block " + std::to_string(b + 1));
    expect_words(path, bh, 4, "node block header");
    const long long parametric = parse_int(path, bh.number, bh.words[2], "parametric flag");
    const int dim = parse_count(path, bh.number, bh.words[0], "entity dimension");
    const int count = parse_count(path, bh.number, bh.words[3], "number of nodes in block");
    std::vector<std::pair<long long, int>> block_tags;
    for (int i = 0; i < count; ++i) {
      const Line& l = r.next("a node tag");
      expect_words(path, l, 1, "node tag");
      block_tags.emplace_back(parse_int(path, l.number, l.words[0], "node tag"), l.number);
    }
    // Parametric nodes carry dim extra coordinates (u, v, w up to the entity's dimension).
    const size_t words = 3 + (parametric != 0 ? static_cast<size_t>(dim) : 0);
    for (int i = 0; i < count; ++i) {
      const Line& l = r.next("node coordinates");
      expect_words(path, l, words, "node coordinates");
      Vec3 p;
      for (int a = 0; a < 3; ++a) p[a] = parse_double(path, l.number, l.words[static_cast<size_t>(a)], "coordinate");
      add_node(mesh, tags, path, block_tags[static_cast<size_t>(i)].second, block_tags[static_cast<size_t>(i)].first, p);
    }
  }
  if (mesh.vertices.rows() != total)
    throw MeshError(path, h.number, "the header declares " + std::to_string(total) + " nodes, the blocks hold " +
                                        std::to_string(mesh.vertices.rows()));
  expect_end(r, "$EndNodes");
}

void read_gmsh41_elements(LineReader& r, TetMesh& mesh, const TagMap& tags) {
  const std::string& path = r.path();
  // numEntityBlocks numElements minElementTag maxElementTag
  const Line& h = r.next("the $Elements header");
  expect_words(path, h, 4, "$Elements header");
  const int blocks = parse_count(path, h.number, h.words[0], "number of entity blocks");
  const int total = parse_count(path, h.number, h.words[1], "number of elements");
  int seen = 0;
  for (int b = 0; b < blocks; ++b) {
    // entityDim entityTag elementType numElementsInBlock, then: elementTag node...
    const Line& bh = r.next("element block " + std::to_string(b + 1));
    expect_words(path, bh, 4, "element block header");
    const long long type = parse_int(path, bh.number, bh.words[2], "element type");
    const int count = parse_count(path, bh.number, bh.words[3], "number of elements in block");
    const int nodes = gmsh_nodes_of_type(type);
    for (int e = 0; e < count; ++e) {
      const Line& l = r.next("an element");
      if (nodes > 0) expect_words(path, l, static_cast<size_t>(1 + nodes), "element");
      if (type != 4) continue;
      std::array<int, 4> t{};
      for (int k = 0; k < 4; ++k)
        t[static_cast<size_t>(k)] = node_index(tags, path, l.number, l.words[static_cast<size_t>(1 + k)]);
      mesh.tets.push_back(t);
    }
    seen += count;
  }
  if (seen != total)
    throw MeshError(path, h.number, "the header declares " + std::to_string(total) + " elements, the blocks hold " +
                                        std::to_string(seen));
  expect_end(r, "$EndElements");
}

}  // namespace

TetMesh read_gmsh(const std::string& path) {
  LineReader r(path, 0);
  TetMesh mesh;
  mesh.vertices.resize(0, 3);
  TagMap tags;
  int version = 0;  // 22 or 41
  bool have_nodes = false, have_elements = false;
  while (!r.done()) {
    const Line& l = r.next("a section");
    const std::string_view section = l.words[0];
    if (section == "$MeshFormat") {
      const Line& f = r.next("the format line");
      expect_words(path, f, 3, "format line (version, file type, data size)");
      const std::string_view v = f.words[0];
      if (v == "2.2") {
        version = 22;
      } else if (v == "4.1") {
        version = 41;
      } else {
        throw MeshError(path, f.number, "format version " + std::string(v) + " is not supported (2.2 or 4.1)");
      }
      if (f.words[1] != "0")
        throw MeshError(path, f.number, "file type " + std::string(f.words[1]) + " is not supported (0 = ASCII)");
      expect_end(r, "$EndMeshFormat");
    } else if (section == "$Nodes" || section == "$Elements") {
      if (version == 0) throw MeshError(path, l.number, std::string(section) + " before $MeshFormat");
      if (section == "$Nodes") {
        if (have_nodes) throw MeshError(path, l.number, "a second $Nodes section");
        if (version == 22) read_gmsh22_nodes(r, mesh, tags); else read_gmsh41_nodes(r, mesh, tags);
        have_nodes = true;
      } else {
        if (!have_nodes) throw MeshError(path, l.number, "$Elements before $Nodes");
        if (have_elements) throw MeshError(path, l.number, "a second $Elements section");
        if (version == 22) read_gmsh22_elements(r, mesh, tags); else read_gmsh41_elements(r, mesh, tags);
        have_elements = true;
      }
    } else if (!section.empty() && section[0] == '$') {
      // Other sections ($PhysicalNames, $Entities, ...) are skipped.
      skip_section(r, "$End" + std::string(section.substr(1)));
    } else {
      throw MeshError(path, l.number, "expected a section such as $Nodes, found '" + std::string(section) + "'");
    }
  }
  if (version == 0) throw MeshError(path, 0, "no $MeshFormat section");
  if (!have_nodes) throw MeshError(path, 0, "no $Nodes section");
  if (!have_elements) throw MeshError(path, 0, "no $Elements section");
  return mesh;
}

TetMesh read_tet_mesh(const std::string& path) {
  const std::string ext = lower_extension(path);
  if (ext == ".msh") return read_gmsh(path);
  if (ext == ".node" || ext == ".ele" || ext.empty()) return read_tetgen(path);
  throw MeshError(path, 0, "unknown tet mesh extension '" + ext + "' (.node, .ele or .msh)");
}

// ---------------------------------------------------------------------------------------------
// Bodies from meshes.

namespace {

double bounding_box_diagonal(const Points& x) {
  if (x.rows() == 0) return 0.0;
  return (x.colwise().maxCoeff() - x.colwise().minCoeff()).norm();
}

// Throws MeshError (line 0) naming the first pair of vertices with identical coordinates.
void check_duplicate_vertices(const Points& x, const std::string& file) {
  std::vector<int> order(static_cast<size_t>(x.rows()));
  std::iota(order.begin(), order.end(), 0);
  auto key = [&](int i) { return std::make_tuple(x(i, 0), x(i, 1), x(i, 2)); };
  std::sort(order.begin(), order.end(), [&](int a, int b) { return std::make_pair(key(a), a) < std::make_pair(key(b), b); });
  for (size_t k = 1; k < order.size(); ++k) {
    if (key(order[k - 1]) == key(order[k])) {
      const int a = order[k - 1], b = order[k];
      throw MeshError(file, 0, "vertices " + std::to_string(a) + " and " + std::to_string(b) +
                                   " have identical coordinates " +
                                   format_vec3(x.row(a).transpose(), kShortDigits));
    }
  }
}

void check_finite_vertices(const Points& x, const std::string& file) {
  for (Eigen::Index i = 0; i < x.rows(); ++i)
    if (!x.row(i).allFinite())
      throw MeshError(file, 0, "vertex " + std::to_string(i) + " has a non-finite coordinate");
}

template <size_t K>
void check_indices(const std::vector<std::array<int, K>>& elements, int n, const char* name,
                   const std::string& file) {
  for (size_t e = 0; e < elements.size(); ++e)
    for (int v : elements[e])
      if (v < 0 || v >= n)
        throw MeshError(file, 0, std::string(name) + " " + std::to_string(e) + ": vertex index " +
                                     std::to_string(v) + " is out of range [0, " + std::to_string(n) + ")");
}

// The unique undirected edges of a set of elements, each (min, max), sorted.
template <size_t K>
std::vector<std::array<int, 2>> unique_edges(const std::vector<std::array<int, K>>& elements) {
  std::vector<std::array<int, 2>> edges;
  for (const auto& e : elements)
    for (size_t a = 0; a < K; ++a)
      for (size_t b = a + 1; b < K; ++b) edges.push_back({std::min(e[a], e[b]), std::max(e[a], e[b])});
  std::sort(edges.begin(), edges.end());
  edges.erase(std::unique(edges.begin(), edges.end()), edges.end());
  return edges;
}

// The surface's union with what the model already had is closed only when both are.
void merge_closed(Model& model, bool had_triangles, bool closed) {
  model.surface_closed = (had_triangles ? model.surface_closed : true) && closed;
}

}  // namespace

ParticleRange add_surface_mesh(Model& model, const SurfaceMesh& mesh, const SurfaceBodySpec& spec,
                               const std::string& file) {
  require_positive("SurfaceBodySpec.mass", spec.mass, kShortDigits);
  require_positive("SurfaceBodySpec.radius", spec.radius, kShortDigits);
  require_params("SurfaceBodySpec.stretch", spec.stretch, kShortDigits);
  require_params("SurfaceBodySpec.bending_params", spec.bending_params, kShortDigits);
  const int n = static_cast<int>(mesh.vertices.rows());
  if (n < 3) throw MeshError(file, 0, "a surface needs at least 3 vertices, found " + std::to_string(n));
  if (mesh.triangles.empty()) throw MeshError(file, 0, "no triangles");
  check_finite_vertices(mesh.vertices, file);
  check_indices(mesh.triangles, n, "triangle", file);
  check_duplicate_vertices(mesh.vertices, file);
  // Zero area relative to the mesh's size: area <= 1e-12 diag^2 (diag: bounding-box diagonal).
  const double diag = bounding_box_diagonal(mesh.vertices);
  for (size_t t = 0; t < mesh.triangles.size(); ++t) {
    const auto& tri = mesh.triangles[t];
    const Vec3 a = mesh.vertices.row(tri[0]), b = mesh.vertices.row(tri[1]), c = mesh.vertices.row(tri[2]);
    const double area = 0.5 * (b - a).cross(c - a).norm();
    if (area <= 1e-12 * diag * diag)
      throw MeshError(file, 0, "triangle " + std::to_string(t) + " (vertices " + index_list(tri, 3) +
                                   ") has zero area (" + format_number(area, kShortDigits) + " m^2)");
  }

  // Closed: every undirected edge in exactly two triangles, traversed once in each direction.
  std::map<std::pair<int, int>, int> directed;
  for (const auto& tri : mesh.triangles)
    for (size_t e = 0; e < 3; ++e) ++directed[{tri[e], tri[(e + 1) % 3]}];
  bool closed = true;
  for (const auto& [edge, count] : directed) {
    const auto twin = directed.find({edge.second, edge.first});
    if (count != 1 || twin == directed.end() || twin->second != 1) closed = false;
  }
  // A dihedral bending constraint needs an edge shared by exactly two triangles: an edge of more
  // (non-manifold) would silently get none, so with bending such a surface is refused, saying
  // what would be dropped.
  if (spec.bending) {
    std::map<std::pair<int, int>, int> uses;
    for (const auto& tri : mesh.triangles)
      for (size_t e = 0; e < 3; ++e) ++uses[{std::min(tri[e], tri[(e + 1) % 3]), std::max(tri[e], tri[(e + 1) % 3])}];
    int non_manifold = 0, interior = 0;
    std::pair<int, int> first{-1, -1};
    int first_uses = 0;
    for (const auto& [edge, count] : uses) {
      if (count == 2) ++interior;
      if (count > 2 && non_manifold++ == 0) {
        first = edge;
        first_uses = count;
      }
    }
    if (non_manifold > 0)
      throw MeshError(file, 0, std::to_string(non_manifold) + " non-manifold edge" + (non_manifold == 1 ? "" : "s") +
                                   " (shared by more than two triangles; the first: vertices " +
                                   std::to_string(first.first) + " and " + std::to_string(first.second) + ", " +
                                   std::to_string(first_uses) + " triangles): a dihedral bending constraint needs "
                                   "exactly two, so they would get none (the " + std::to_string(interior) +
                                   " edges shared by two would keep theirs); fix the mesh, or import it "
                                   "without bending (bending = false)");
  }
  // A closed surface wound inward (negative enclosed volume) is turned outward, as Model asks.
  std::vector<std::array<int, 3>> triangles = mesh.triangles;
  if (closed) {
    double volume = 0.0;
    for (const auto& tri : triangles)
      volume += Vec3(mesh.vertices.row(tri[0])).dot(Vec3(mesh.vertices.row(tri[1])).cross(Vec3(mesh.vertices.row(tri[2])))) / 6.0;
    if (volume < 0.0)
      for (auto& tri : triangles) std::swap(tri[1], tri[2]);
  }

  const int begin = append_particles(model, mesh.vertices,
                                     std::vector<double>(static_cast<size_t>(n), spec.mass / n), spec.radius);
  for (auto& tri : triangles)
    for (int& v : tri) v += begin;
  const bool had_triangles = !model.triangles.empty();
  model.triangles.insert(model.triangles.end(), triangles.begin(), triangles.end());
  merge_closed(model, had_triangles, closed);

  const std::uint16_t stretch = model.group_index("stretch");
  for (const auto& e : unique_edges(triangles)) {
    model.edges.push_back(e);
    add_distance(model, e[0], e[1], spec.stretch, stretch);
  }
  if (spec.bending) {
    // One dihedral constraint per edge shared by exactly two triangles.
    add_dihedral_bending(model, triangles, spec.bending_params, model.group_index("bending"));
  }
  return {begin, begin + n};
}

ParticleRange add_tet_mesh(Model& model, const TetMesh& mesh, const TetBodySpec& spec, const std::string& file) {
  require_positive("TetBodySpec.density", spec.density, kShortDigits);
  require_positive("TetBodySpec.radius", spec.radius, kShortDigits);
  require_params("TetBodySpec.edge", spec.edge, kShortDigits);
  require_params("TetBodySpec.volume", spec.volume, kShortDigits);
  const int n = static_cast<int>(mesh.vertices.rows());
  if (mesh.tets.empty()) throw MeshError(file, 0, "no tetrahedra");
  check_finite_vertices(mesh.vertices, file);
  check_indices(mesh.tets, n, "tet", file);
  check_duplicate_vertices(mesh.vertices, file);

  const double diag = bounding_box_diagonal(mesh.vertices);
  const double min_volume = 1e-12 * diag * diag * diag;
  std::vector<std::array<int, 4>> tets = mesh.tets;
  std::vector<double> volumes(tets.size());
  std::vector<double> masses(static_cast<size_t>(n), 0.0);
  for (size_t e = 0; e < tets.size(); ++e) {
    auto& t = tets[e];
    double v = tet_signed_volume(mesh.vertices.row(t[0]), mesh.vertices.row(t[1]), mesh.vertices.row(t[2]),
                                 mesh.vertices.row(t[3]));
    if (!(std::abs(v) >= min_volume))
      throw MeshError(file, 0, "tet " + std::to_string(e) + " (vertices " + index_list(mesh.tets[e], 4) +
                                   ") is degenerate: volume " + format_number(v, kShortDigits) + " m^3 is below 1e-12 * diag^3 = " +
                                   format_number(min_volume, kShortDigits) + " m^3");
    if (v < 0.0 && !spec.reorient)
      throw MeshError(file, 0, "tet " + std::to_string(e) + " (vertices " + index_list(mesh.tets[e], 4) +
                                   ") is negatively oriented (volume " + format_number(v, kShortDigits) +
                                   " m^3): refused with reorient = false; reorient = true flips it "
                                   "(a study of inverted tets stages them with [defects] flip_tets)");
    if (v < 0.0) {
      std::swap(t[2], t[3]);
      v = -v;
    }
    volumes[e] = v;
    for (int k : t) masses[static_cast<size_t>(k)] += spec.density * std::abs(v) / 4.0;
  }
  for (int i = 0; i < n; ++i)
    if (masses[static_cast<size_t>(i)] == 0.0)
      throw MeshError(file, 0, "vertex " + std::to_string(i) + " belongs to no tet, so it would have no mass");

  // Boundary faces: faces of exactly one tet. Each tet's faces (1 2 3), (0 3 2), (0 1 3), (0 2 1)
  // point outward when the tet is positive; a negative tet (kept when !reorient) flips them.
  static constexpr std::array<std::array<int, 3>, 4> kFaces{{{1, 2, 3}, {0, 3, 2}, {0, 1, 3}, {0, 2, 1}}};
  std::map<std::array<int, 3>, int> face_count;
  auto face_key = [](std::array<int, 3> f) {
    std::sort(f.begin(), f.end());
    return f;
  };
  for (const auto& t : tets)
    for (const auto& f : kFaces) ++face_count[face_key({t[static_cast<size_t>(f[0])], t[static_cast<size_t>(f[1])], t[static_cast<size_t>(f[2])]})];
  std::vector<std::array<int, 3>> surface;
  for (size_t e = 0; e < tets.size(); ++e) {
    const auto& t = tets[e];
    for (const auto& f : kFaces) {
      std::array<int, 3> tri{t[static_cast<size_t>(f[0])], t[static_cast<size_t>(f[1])], t[static_cast<size_t>(f[2])]};
      if (face_count[face_key(tri)] != 1) continue;
      if (volumes[e] < 0.0) std::swap(tri[1], tri[2]);
      surface.push_back(tri);
    }
  }

  const int begin = append_particles(model, mesh.vertices, masses, spec.radius);
  for (auto& t : tets)
    for (int& v : t) v += begin;
  for (auto& tri : surface)
    for (int& v : tri) v += begin;
  model.tets.insert(model.tets.end(), tets.begin(), tets.end());
  const bool had_triangles = !model.triangles.empty();
  model.triangles.insert(model.triangles.end(), surface.begin(), surface.end());
  // The boundary of a tet mesh is closed, and wound outward by construction.
  merge_closed(model, had_triangles, true);

  const std::vector<std::array<int, 2>> edges = unique_edges(tets);
  model.edges.insert(model.edges.end(), edges.begin(), edges.end());
  if (spec.edges) {
    const std::uint16_t group = model.group_index("edge");
    for (const auto& e : edges) add_distance(model, e[0], e[1], spec.edge, group);
  }
  if (spec.volumes) {
    const std::uint16_t group = model.group_index("volume");
    for (size_t e = 0; e < tets.size(); ++e)
      model.constraints.push_back(make_constraint(ConstraintKind::Volume, tets[e], volumes[e], spec.volume, group));
  }
  return {begin, begin + n};
}

}  // namespace pbdbench
