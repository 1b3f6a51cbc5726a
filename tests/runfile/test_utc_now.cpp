// Tests of runfile/utc_now: ISO 8601 in UTC, and the time now.
#include "runfile/utc_now.hpp"

#include <gtest/gtest.h>

#include <ctime>
#include <regex>
#include <string>

namespace pbdbench {
namespace {

TEST(runfile_utc_now, Iso8601InUtc) {
  const std::time_t before = std::time(nullptr);
  const std::string now = utc_now();
  const std::time_t after = std::time(nullptr);
  ASSERT_TRUE(std::regex_match(now, std::regex(R"(\d{4}-\d\d-\d\dT\d\d:\d\d:\d\dZ)"))) << now;
  std::tm tm{};
  ASSERT_NE(strptime(now.c_str(), "%Y-%m-%dT%H:%M:%SZ", &tm), nullptr) << now;
  const std::time_t parsed = timegm(&tm);  // read back as UTC
  EXPECT_GE(parsed, before) << now;
  EXPECT_LE(parsed, after) << now;
}

}  // namespace
}  // namespace pbdbench
