// Tests of runfile/regress_file: rows written as columns and read back, an empty report, and a
// file without the columns refused naming the path.
#include "runfile/regress_file.hpp"

#include <gtest/gtest.h>

#include <cmath>
#include <filesystem>
#include <string>
#include <vector>

#include "runfile/compare_file.hpp"
#include "tests/runfile/test_support.hpp"

namespace pbdbench {
namespace {

namespace fs = std::filesystem;

using test::temp_dir;

TEST(runfile_regress_file, RoundTrip) {
  const fs::path path = temp_dir() / "out" / "regress.h5";  // the folder is created
  const double nan = std::numeric_limits<double>::quiet_NaN();
  const std::vector<RegressFileRow> rows = {
      {"chain_xpbd", "energy_drift", "J", "same", 1.5, 1.5, 0.0, 1e-9},
      {"cloth_pbd", "wall_time", "s", "ratio", 2.0, 3.0, 1.5, 0.0},
      {"bar_fem", "volume_drift", "1", "worse", 0.0, nan, nan, 1e-3},
  };
  write_regress_file(path, rows);
  const std::vector<RegressFileRow> back = read_regress_file(path);
  ASSERT_EQ(back.size(), rows.size());
  for (size_t k = 0; k < rows.size(); ++k) {
    SCOPED_TRACE(rows[k].case_name);
    EXPECT_EQ(back[k].case_name, rows[k].case_name);
    EXPECT_EQ(back[k].metric, rows[k].metric);
    EXPECT_EQ(back[k].units, rows[k].units);
    EXPECT_EQ(back[k].verdict, rows[k].verdict);
    EXPECT_EQ(back[k].baseline, rows[k].baseline);
    EXPECT_EQ(back[k].allowed, rows[k].allowed);
    if (std::isnan(rows[k].now)) {
      EXPECT_TRUE(std::isnan(back[k].now));
      EXPECT_TRUE(std::isnan(back[k].change));
    } else {
      EXPECT_EQ(back[k].now, rows[k].now);
      EXPECT_EQ(back[k].change, rows[k].change);
    }
  }
  write_regress_file(path, {});
  EXPECT_TRUE(read_regress_file(path).empty());
}

TEST(runfile_regress_file, RefusesOtherFiles) {
  const fs::path dir = temp_dir();
  test::expect_error([&] { read_regress_file(dir / "missing.h5"); }, {"missing.h5"});
  const fs::path other = dir / "compare.h5";
  write_compare_file(other, CompareResult{});
  test::expect_error([&] { read_regress_file(other); }, {"no column case", other.string()});
}

}  // namespace
}  // namespace pbdbench
