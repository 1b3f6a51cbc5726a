// SHA-256 (FIPS 180-4) of a byte string, as 64 lowercase hex digits: the content hash an
// experiment file is registered under (experiments/registry.hpp).
#pragma once

#include <filesystem>
#include <string>
#include <string_view>

namespace pbdbench::experiments {

std::string sha256_hex(std::string_view bytes);

// The SHA-256 of a file's bytes. Throws std::runtime_error naming the path when it cannot be read.
std::string sha256_file(const std::filesystem::path& path);

}  // namespace pbdbench::experiments
