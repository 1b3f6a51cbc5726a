// libFuzzer target: the scenario loader and the mesh readers on arbitrary bytes.
//
// The first byte picks the reader, the rest is the file:
//   0  a scenario (TOML): config::load_text, then the scene is built (config::build_scene)
//   1  a Wavefront OBJ surface: read_obj, then add_surface_mesh
//   2  a TetGen pair: .node, a NUL byte, .ele: read_tetgen, then add_tet_mesh
//   3  a Gmsh .msh (2.2 or 4.1): read_gmsh, then add_tet_mesh
// Refusals (ConfigError, MeshError, and the other std::exception the builders throw) are the
// expected outcome of bad input; a crash, a sanitizer report, a leak or a timeout is a finding.
// scripts/fuzz.sh builds it (clang, -fsanitize=fuzzer,address,undefined) and runs it, seeded
// with the catalog and tests/bad_input/.
#include <unistd.h>

#include <cstddef>
#include <cstdint>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <string>
#include <string_view>

#include "config/config.hpp"
#include "core/mesh_io.hpp"
#include "core/model.hpp"

namespace {

namespace fs = std::filesystem;

const fs::path& work_dir() {
  static const fs::path dir = [] {
    fs::path d = fs::temp_directory_path() / ("pbdbench-fuzz-" + std::to_string(::getpid()));
    fs::create_directories(d);
    std::atexit([] {
      std::error_code ec;
      fs::remove_all(work_dir(), ec);
    });
    return d;
  }();
  return dir;
}

fs::path write(const std::string& name, std::string_view bytes) {
  const fs::path p = work_dir() / name;
  std::ofstream(p, std::ios::binary | std::ios::trunc).write(bytes.data(), static_cast<std::streamsize>(bytes.size()));
  return p;
}

void run(std::uint8_t mode, std::string_view bytes) {
  using namespace pbdbench;
  switch (mode % 4) {
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
