// The provenance of this build, recorded in every run file. Generated at build time
// (cmake/WriteBuildInfo.cmake): the git commit is never stale. No path of the build machine is
// recorded: the binary finds its data at run time (config/data_dir.hpp).
#pragma once

namespace pbdbench {

struct BuildInfo {
  const char* version;     // project version, e.g. "0.1.0"
  const char* git_commit;  // full hash, with "+dirty" when tracked files were modified
  const char* compiler;    // e.g. "GNU 12.2.0"
  const char* build_type;  // e.g. "Release"
  const char* cxx_flags;   // the flags the sources were compiled with
};

const BuildInfo& build_info();

}  // namespace pbdbench
