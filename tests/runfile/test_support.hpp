// What the tests of runfile/ share: a fresh directory per test, the check that an error names
// what it should, and the check that a file's root attributes are its declared table.
#pragma once

#include <gtest/gtest.h>

#include <filesystem>
#include <fstream>
#include <sstream>
#include <functional>
#include <map>
#include <stdexcept>
#include <string>
#include <vector>

#include "runfile/file_read.hpp"

namespace pbdbench::test {

// A fresh directory for the current test's files, under the build tree.
inline std::filesystem::path temp_dir() {
  const auto* info = ::testing::UnitTest::GetInstance()->current_test_info();
  const std::filesystem::path dir = std::filesystem::path(PBDBENCH_BINARY_DIR) / "tests" / "runfile" /
                                    "tmp" / (std::string(info->test_suite_name()) + "." + info->name());
  std::filesystem::remove_all(dir);
  std::filesystem::create_directories(dir);
  return dir;
}

// `f` throws std::runtime_error whose message contains every one of `parts`.
inline void expect_error(const std::function<void()>& f, const std::vector<std::string>& parts) {
  try {
    f();
    ADD_FAILURE() << "no error; expected one naming " << parts.front();
  } catch (const std::runtime_error& e) {
    for (const std::string& p : parts)
      EXPECT_NE(std::string(e.what()).find(p), std::string::npos) << e.what() << "\nlacks: " << p;
  }
}

// Every root attribute a file has (`read`'s maps: strings and numbers) is declared in `table`
// (a row "<prefix><key>" stands for every name starting with <prefix>), as text or as a number
// as declared; and every row but those patterns is in the file.
template <class Content>
void expect_declared(const FileRead<Content>& read, const std::vector<AttributeInfo>& table) {
  auto row_of = [&](const std::string& name) -> const AttributeInfo* {
    for (const AttributeInfo& a : table) {
      const size_t key = a.name.find("<key>");
      if (a.name == name || (key != std::string::npos && name.rfind(a.name.substr(0, key), 0) == 0)) return &a;
    }
    return nullptr;
  };
  for (const auto& [name, value] : read.attributes) {
    const AttributeInfo* a = row_of(name);
    ASSERT_NE(a, nullptr) << "the root attribute " << name << " is written but not declared";
    EXPECT_EQ(a->type, AttributeType::Text) << name;
  }
  for (const auto& [name, value] : read.numbers) {
    const AttributeInfo* a = row_of(name);
    ASSERT_NE(a, nullptr) << "the root attribute " << name << " is written but not declared";
    EXPECT_NE(a->type, AttributeType::Text) << name;
  }
  for (const AttributeInfo& a : table) {
    if (a.name.find("<key>") == std::string::npos) {
      EXPECT_TRUE(read.attributes.count(a.name) + read.numbers.count(a.name) == 1) << a.name << " is not written";
    }
  }
}

// results/README.md carries `markdown` (a layout's table) verbatim.
inline void expect_readme_carries(const std::string& markdown, const std::string& what) {
  const std::string readme = std::string(PBDBENCH_SOURCE_DIR) + "/results/README.md";
  std::ifstream in(readme);
  ASSERT_TRUE(in) << readme;
  std::stringstream text;
  text << in.rdbuf();
  EXPECT_NE(text.str().find(markdown), std::string::npos)
      << readme << " does not carry " << what << " verbatim; paste this:\n" << markdown;
}

}  // namespace pbdbench::test
