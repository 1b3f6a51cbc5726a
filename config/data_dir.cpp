#include "config/data_dir.hpp"

#include <cstdlib>
#include <stdexcept>
#include <system_error>
#include <vector>

#include "config/config.hpp"

namespace pbdbench::config {

namespace fs = std::filesystem;

namespace {
bool holds_data(const fs::path& dir) {
  std::error_code ec;
  return fs::is_directory(dir / "scenarios", ec);
}
}  // namespace

fs::path executable_path() {
  std::error_code ec;
  const fs::path p = fs::read_symlink("/proc/self/exe", ec);
  if (ec) throw std::runtime_error("cannot locate the running executable (/proc/self/exe): " + ec.message());
  return p;
}

fs::path data_dir() {
  if (const char* env = std::getenv("PBDBENCH_DATA_DIR"); env != nullptr && *env != '\0') {
    const fs::path dir(env);
    if (!holds_data(dir))
      throw ConfigError(Source{"PBDBENCH_DATA_DIR", 0}, "",
                        "PBDBENCH_DATA_DIR=" + dir.string() +
                            " holds no scenarios/: set it to an installation's share/pbdbench or to a "
                            "pbdbench source checkout, or unset it");
    return dir;
  }
  std::vector<fs::path> tried;
  fs::path bin_dir;
  try {
    bin_dir = executable_path().parent_path();
  } catch (const std::runtime_error& e) {
    throw ConfigError(Source{"PBDBENCH_DATA_DIR", 0}, "",
                      std::string(e.what()) + "; set PBDBENCH_DATA_DIR to pbdbench's share/pbdbench");
  }
  for (const fs::path& candidate : {bin_dir.parent_path() / "share" / "pbdbench", bin_dir / "share" / "pbdbench"}) {
    if (holds_data(candidate)) return fs::canonical(candidate);  // the build tree's link resolved
    tried.push_back(candidate);
  }
  throw ConfigError(Source{"PBDBENCH_DATA_DIR", 0}, "",
                    "cannot find pbdbench's data (scenarios/, experiments, scripts): not in " +
                        tried[0].string() + " (an installation) nor in " + tried[1].string() +
                        " (a build tree); set PBDBENCH_DATA_DIR to the share/pbdbench folder of an "
                        "installation or to a source checkout");
}

bool data_dir_is_checkout() {
  std::error_code ec;
  return fs::is_regular_file(data_dir() / "CMakeLists.txt", ec);
}

}  // namespace pbdbench::config
