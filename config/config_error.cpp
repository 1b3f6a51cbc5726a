#include <utility>

#include "config/config.hpp"

namespace pbdbench::config {

namespace {

std::string located(const Source& source, const std::string& message) {
  if (source.file.empty()) return message;
  if (source.line > 0) return source.file + ":" + std::to_string(source.line) + ": " + message;
  return source.file + ": " + message;
}

}  // namespace

ConfigError::ConfigError(Source source, std::string key, const std::string& message)
    : std::runtime_error(located(source, message)), source_(std::move(source)), key_(std::move(key)) {}

}  // namespace pbdbench::config
