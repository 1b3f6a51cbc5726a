#include "experiments/provenance.hpp"

#include <fstream>
#include <thread>

#include <fmt/format.h>

#include "runfile/build_info.hpp"

namespace pbdbench::experiments {

std::string machine_description() {
  std::string model = "unknown CPU";
  std::ifstream in("/proc/cpuinfo");
  for (std::string line; std::getline(in, line);) {
    if (line.rfind("model name", 0) == 0) {
      const size_t colon = line.find(':');
      if (colon != std::string::npos) model = line.substr(colon + 2);
      break;
    }
  }
  return fmt::format("{}, {} cores", model, std::thread::hardware_concurrency());
}

std::string build_description() {
  const BuildInfo& b = build_info();
  return fmt::format("pbdbench {} ({} build, {}, commit {})", b.version, b.build_type, b.compiler, b.git_commit);
}

}  // namespace pbdbench::experiments
