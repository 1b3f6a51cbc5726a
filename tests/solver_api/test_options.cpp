// Tests of solver_api/options.cpp: what solver.threads = 0 resolves to.
#include <gtest/gtest.h>

#include <cstdlib>
#include <string>

#include "solver_api/options.hpp"

namespace pbdbench::test {
namespace {

// Sets PBDBENCH_CORES for the scope and restores what was there.
class CoresShare {
 public:
  explicit CoresShare(const char* value) {
    if (const char* old = std::getenv(kCoresVariable)) old_ = old, had_ = true;
    if (value != nullptr) ::setenv(kCoresVariable, value, 1);
    else ::unsetenv(kCoresVariable);
  }
  ~CoresShare() {
    if (had_) ::setenv(kCoresVariable, old_.c_str(), 1);
    else ::unsetenv(kCoresVariable);
  }

 private:
  std::string old_;
  bool had_ = false;
};

TEST(Options, ThreadsResolveToTheCoresOrTheShareASweepGives) {
  int all = 0;
  {
    const CoresShare none(nullptr);
    all = available_cores();
    EXPECT_GE(all, 1);
    EXPECT_EQ(resolve_threads(0), all);
    EXPECT_EQ(resolve_threads(3), 3);  // an explicit count is taken as it is
  }
  {
    const CoresShare one("1");  // sweep --jobs N on N cores or fewer
    EXPECT_EQ(available_cores(), 1);
    EXPECT_EQ(resolve_threads(0), 1);
    EXPECT_EQ(resolve_threads(2), 2);
  }
  {
    const CoresShare many("4096");  // a share above the cores there are: the cores
    EXPECT_EQ(available_cores(), all);
  }
  for (const char* bad : {"0", "-2", "two", "3x", ""}) {
    const CoresShare share(bad);  // not a whole number >= 1: ignored
    EXPECT_EQ(available_cores(), all) << "'" << bad << "'";
  }
}

TEST(Options, ThreadsAreValidated) {
  SolverOptions o;
  o.threads = -1;
  EXPECT_NE(o.validate().find("solver.threads"), std::string::npos);
  o.threads = 1025;
  EXPECT_NE(o.validate().find("solver.threads"), std::string::npos);
  o.threads = 0;
  EXPECT_EQ(o.validate(), "");
}

}  // namespace
}  // namespace pbdbench::test
