// libFuzzer target: experiment files (claims/experiments/*.toml, reproductions/experiments/) on
// arbitrary bytes, through experiments::load_experiment without the configurations' check (so
// that an input is the file's own keys, runs, measures and rules, and returns in microseconds).
// The file is written as <id>.toml when its `id` is a plain name, since the loader refuses an id
// that is not the file's name before it reads the runs and rules. Refusals (ExperimentError and
// the other std::exception) are the expected outcome; a crash, a sanitizer report, a leak or a
// timeout is a finding. `scripts/fuzz.sh --experiments` builds and runs it, seeded with the
// experiment files of claims/ and reproductions/ and tests/fuzz/make_seeds.py's rules.
#include <algorithm>
#include <cctype>
#include <cstddef>
#include <cstdint>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <string>
#include <string_view>

#include <toml++/toml.h>

#include "experiments/experiment.hpp"
#include "tests/fuzz/work_dir.hpp"

namespace {

namespace fs = std::filesystem;

const fs::path& work_dir() { return pbdbench::fuzz::work_dir("pbdbench-fuzz-experiment"); }

// The file's `id` when it is a plain file name, else "fuzz".
std::string stem_of(std::string_view bytes) {
  try {
    const toml::table t = toml::parse(bytes);
    if (const auto id = t["id"].value<std::string>();
        id && !id->empty() && id->size() < 64 && id->front() != '.' &&
        std::all_of(id->begin(), id->end(), [](char c) {
          return std::isalnum(static_cast<unsigned char>(c)) || c == '.' || c == '-' || c == '_';
        }))
      return *id;
  } catch (const std::exception&) {
  }
  return "fuzz";
}

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  const std::string_view bytes(reinterpret_cast<const char*>(data), size);
  const fs::path file = work_dir() / (stem_of(bytes) + ".toml");
  std::ofstream(file, std::ios::binary | std::ios::trunc).write(bytes.data(), static_cast<std::streamsize>(bytes.size()));
  try {
    (void)pbdbench::experiments::load_experiment(file, false);
  } catch (const std::exception&) {
    // Refused: what bad input should get.
  }
  std::error_code ec;
  fs::remove(file, ec);
  return 0;
}
