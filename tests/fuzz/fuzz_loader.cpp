// libFuzzer target: the scenario loader and the mesh readers on arbitrary bytes.
//
// The first byte picks the reader, the rest is the file:
//   0  a scenario (TOML): config::load_text, then the scene is built (config::build_scene)
//   1  a Wavefront OBJ surface: read_obj, then add_surface_mesh
//   2  a TetGen pair: .node, a NUL byte, .ele: read_tetgen, then add_tet_mesh
//   3  a Gmsh .msh (2.2 or 4.1): read_gmsh, then add_tet_mesh
//   4  a rule or measure of an experiment file (experiments/expression.hpp): parsed, its names
//      listed, then evaluated over a scope of a few scalars (0, 1, inf, NaN) and a series
// Refusals (ConfigError, MeshError, and the other std::exception the builders throw) are the
// expected outcome of bad input; a crash, a sanitizer report, a leak or a timeout is a finding.
// scripts/fuzz.sh builds it (clang, -fsanitize=fuzzer,address,undefined) and runs it, seeded
// with the catalog and tests/bad_input/.
#include <cstddef>
#include <cstdint>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <limits>
#include <optional>
#include <string>
#include <string_view>
#include <vector>

#include "config/config.hpp"
#include "core/mesh_io.hpp"
#include "core/model.hpp"
#include "experiments/expression.hpp"
#include "tests/fuzz/work_dir.hpp"

namespace {

namespace fs = std::filesystem;

const fs::path& work_dir() { return pbdbench::fuzz::work_dir("pbdbench-fuzz"); }

fs::path write(const std::string& name, std::string_view bytes) {
  const fs::path p = work_dir() / name;
  std::ofstream(p, std::ios::binary | std::ios::trunc).write(bytes.data(), static_cast<std::streamsize>(bytes.size()));
  return p;
}

// What the names of a fuzzed expression stand for: a, b, zero, big (inf) and nan, and the
// series s and time over five rows; any other name is unknown (a refusal).
class FuzzScope final : public pbdbench::experiments::Scope {
 public:
  std::optional<double> scalar(const std::string& name) const override {
    if (name == "a") return 1.0;
    if (name == "b") return -2.5;
    if (name == "zero") return 0.0;
    if (name == "big") return std::numeric_limits<double>::infinity();
    if (name == "nan") return std::numeric_limits<double>::quiet_NaN();
    return std::nullopt;
  }
  const std::vector<double>* series(const std::string& name) const override {
    if (name == "time") return &time_;
    if (name == "s") return &s_;
    return nullptr;
  }
  const std::vector<double>* times() const override { return &time_; }

 private:
  std::vector<double> time_ = {0.0, 0.1, 0.2, 0.3, 0.4};
  std::vector<double> s_ = {1.0, -1.0, 2.0, std::numeric_limits<double>::infinity(), 0.5};
};

void run(std::uint8_t mode, std::string_view bytes) {
  using namespace pbdbench;
  switch (mode % 5) {
    case 0: {
      const config::Config c = config::load_text(std::string(bytes), work_dir() / "fuzz.toml");
      (void)config::build_scene(c);
      break;
    }
    case 1: {
      const SurfaceMesh mesh = read_obj(write("fuzz.obj", bytes).string());
      Model m;
      add_surface_mesh(m, mesh, SurfaceBodySpec{}, "fuzz.obj");
      break;
    }
    case 2: {
      const auto nul = bytes.find('\0');
      write("fuzz.node", bytes.substr(0, nul));
      write("fuzz.ele", nul == std::string_view::npos ? std::string_view() : bytes.substr(nul + 1));
      const TetMesh mesh = read_tetgen((work_dir() / "fuzz.node").string());
      Model m;
      add_tet_mesh(m, mesh, TetBodySpec{}, "fuzz.node");
      break;
    }
    case 3: {
      const TetMesh mesh = read_gmsh(write("fuzz.msh", bytes).string());
      Model m;
      add_tet_mesh(m, mesh, TetBodySpec{}, "fuzz.msh");
      break;
    }
    case 4: {
      const experiments::Expression e{std::string(bytes)};
      (void)e.scalar_names();
      (void)e.series_names();
      const FuzzScope scope;
      (void)e.evaluate_checked(scope);
      (void)e.nan_names(scope);
      break;
    }
  }
}

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  if (size == 0) return 0;
  try {
    run(data[0], std::string_view(reinterpret_cast<const char*>(data) + 1, size - 1));
  } catch (const std::exception&) {
    // Refused: what bad input should get. The message is checked by tests/bad_input/.
  }
  return 0;
}
