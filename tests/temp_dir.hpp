// A fresh folder for one test, unique to its process (CTest runs tests side by side, each
// GoogleTest case in a process of its own), removed with the object.
#pragma once

#include <unistd.h>

#include <filesystem>
#include <fstream>
#include <string>

namespace pbdbench::testing {

class TempDir {
 public:
  // <temp>/pbdbench_<name>_<pid>_<k>, k counting the folders this process made.
  explicit TempDir(const std::string& name) {
    static int made = 0;
    path_ = std::filesystem::temp_directory_path() /
            ("pbdbench_" + name + "_" + std::to_string(::getpid()) + "_" + std::to_string(made++));
    std::filesystem::remove_all(path_);
    std::filesystem::create_directories(path_);
  }
  ~TempDir() {
    std::error_code ec;
    std::filesystem::remove_all(path_, ec);
  }
  TempDir(const TempDir&) = delete;
  TempDir& operator=(const TempDir&) = delete;

  const std::filesystem::path& path() const { return path_; }
  std::filesystem::path operator/(const std::filesystem::path& p) const { return path_ / p; }
  std::filesystem::path write(const std::string& name, const std::string& text) const {
    const std::filesystem::path p = path_ / name;
    std::ofstream(p) << text;
    return p;
  }

 private:
  std::filesystem::path path_;
};

}  // namespace pbdbench::testing
