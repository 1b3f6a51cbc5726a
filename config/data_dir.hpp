// Where pbdbench finds its data at run time: the scenario catalog, the experiments of the claims
// and reproductions, the regression registry and baselines, the studies and the Python scripts.
// Never a path compiled into the binary, so that a build tree that is copied or moved, and an
// installation (`cmake --install build --prefix P`), work wherever they are. The first of these
// that holds scenarios/ is the data folder:
//
//   1. $PBDBENCH_DATA_DIR, when set: an installation's share/pbdbench, or a source checkout
//      (when it is set and holds no scenarios/, that is an error: a typo must not fall through);
//   2. <folder of the running executable>/../share/pbdbench: an installation (P/bin/pbdbench,
//      P/share/pbdbench);
//   3. <folder of the running executable>/share/pbdbench: a build tree, where CMake links it to
//      the sources the tree was configured from (a relative link: a checkout copied with its
//      build folder inside still finds its own sources).
//
// $PBDBENCH_SCENARIOS and $PBDBENCH_CLAIMS still override the catalog and the claims' folder
// alone (config/config.hpp, experiments/experiment.hpp).
#pragma once

#include <filesystem>
#include <string>

namespace pbdbench::config {

// The data folder (see above). Throws ConfigError naming what was tried when none is found.
std::filesystem::path data_dir();

// True when the data folder is a source checkout (it has CMakeLists.txt) rather than an
// installation: then it is the place for files the repository keeps (the regression baselines).
bool data_dir_is_checkout();

// The running executable (/proc/self/exe, links resolved). Throws std::runtime_error when the
// system does not say.
std::filesystem::path executable_path();

}  // namespace pbdbench::config
