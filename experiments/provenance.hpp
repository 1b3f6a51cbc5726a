// Where a result was measured: the machine (CPU model from /proc/cpuinfo, cores) and the build
// (version, build type, compiler, commit). Every report and every timing record states both.
#pragma once

#include <string>

namespace pbdbench::experiments {

// e.g. "AMD EPYC 7B13, 2 cores"
std::string machine_description();
// e.g. "pbdbench 0.1.0 (Release build, GNU 12.2.0, commit abc123)"
std::string build_description();

}  // namespace pbdbench::experiments
