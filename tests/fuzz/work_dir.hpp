// The fuzz targets' scratch folder: one per process under the temporary folder, removed at exit.
#pragma once

#include <unistd.h>

#include <cstdlib>
#include <filesystem>
#include <string>

namespace pbdbench::fuzz {

// <tmp>/<prefix>-<pid>, created on the first call.
inline const std::filesystem::path& work_dir(const char* prefix) {
  static const std::filesystem::path dir = [prefix] {
    std::filesystem::path d = std::filesystem::temp_directory_path() / (std::string(prefix) + "-" + std::to_string(::getpid()));
    std::filesystem::create_directories(d);
    std::atexit([] {
      std::error_code ec;
      std::filesystem::remove_all(dir, ec);
    });
    return d;
  }();
  return dir;
}

}  // namespace pbdbench::fuzz
