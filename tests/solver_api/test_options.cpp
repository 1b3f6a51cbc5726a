// Tests of solver_api/options.cpp: what solver.threads = 0 resolves to; the option rows (each
// option declared once: its setter, its value and its check).
#include <gtest/gtest.h>

#include <cstdlib>
#include <limits>
#include <stdexcept>
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

// Every row: a unique solver.* key, a getter and a setter that write the field the getter reads,
// a default (SolverOptions{}) that passes validate().
TEST(OptionRows, EachRowReadsAndWritesItsField) {
  const SolverOptions defaults;
  EXPECT_EQ(defaults.validate(), "");
  const auto& rows = solver_option_rows();
  ASSERT_GE(rows.size(), 40u);
  for (size_t i = 0; i < rows.size(); ++i) {
    const OptionRow& r = rows[i];
    SCOPED_TRACE(r.key);
    EXPECT_EQ(r.key.rfind("solver.", 0), 0u);
    EXPECT_FALSE(r.doc.empty());
    EXPECT_EQ(find_solver_option(r.key), &r);
    for (size_t j = 0; j < i; ++j) EXPECT_NE(r.key, rows[j].key);
    // Write the default back: nothing changes; then a changed value is read back.
    SolverOptions o;
    r.set(o, r.get(defaults));
    EXPECT_EQ(r.get(o), r.get(defaults));
    OptionValue other = r.get(defaults);
    if (auto* b = std::get_if<bool>(&other)) *b = !*b;
    else if (auto* n = std::get_if<std::int64_t>(&other)) *n += 1;
    else if (auto* d = std::get_if<double>(&other)) *d = *d == 0.0 ? 0.5 : *d * 0.5;
    else if (auto* t = std::get_if<std::string>(&other)) {
      if (r.choices.size() < 2) continue;
      *t = r.choices[r.choices[0] == *t ? 1 : 0];
    } else if (auto* l = std::get_if<std::vector<std::string>>(&other)) {
      ASSERT_FALSE(r.choices.empty());
      l->push_back(r.choices.back());
    }
    r.set(o, other);
    EXPECT_EQ(r.get(o), other);
    EXPECT_NE(r.get(o), r.get(defaults));
  }
  EXPECT_EQ(find_solver_option("solver.unknown"), nullptr);
}

// validate() checks each row's bounds and choices, naming the key and the bound.
TEST(OptionRows, ValidateUsesTheRowsBounds) {
  SolverOptions o;
  o.iterations = 0;
  EXPECT_EQ(o.validate(), "solver.iterations = 0 is below the minimum 1");
  o = {};
  o.jacobi_relaxation = 0.0;
  EXPECT_EQ(o.validate(), "solver.jacobi_relaxation = 0 must be greater than 0");
  o = {};
  o.ref_rtol = 1.0;
  EXPECT_EQ(o.validate(), "solver.ref.rtol = 1 must be less than 1");
  o = {};
  o.contact_margin = std::numeric_limits<double>::infinity();
  EXPECT_EQ(o.validate(), "solver.contact_margin = inf is not a finite number");
  o = {};
  o.seed_backup = "later";
  EXPECT_EQ(o.validate(), "solver.seed.backup = 'later' is not one of before_forces, after_damping");
  o = {};
  o.seed_fixes = {"D1", "D12"};
  EXPECT_NE(o.validate().find("solver.seed.fixes: 'D12'"), std::string::npos);
  o = {};
  o.seed_dynamic_inverse_mass = o.seed_graded_inverse_mass = true;
  EXPECT_NE(o.validate().find("choose one"), std::string::npos);
  // An enum's row refuses a name it does not know.
  SolverOptions e;
  EXPECT_THROW(find_solver_option("solver.order")->set(e, std::string("sideways")), std::invalid_argument);
}

// Each row says which families read it: the [solver.<family>] tables belong to their family
// alone, the shared keys to the families that read them.
TEST(SolverFamilies, RowsNameTheFamiliesThatReadThem) {
  auto applies = [](const char* key, SolverFamily f) {
    const OptionRow* r = find_solver_option(key);
    EXPECT_NE(r, nullptr) << key;
    return r != nullptr && option_applies(*r, f);
  };
  const std::pair<const char*, SolverFamily> tables[] = {
      {"solver.seed.", SolverFamily::PbdSeed}, {"solver.pbd.", SolverFamily::Pbd},
      {"solver.xpbd.", SolverFamily::Xpbd},    {"solver.force.", SolverFamily::Force},
      {"solver.ref.", SolverFamily::Reference}, {"solver.global.", SolverFamily::Global}};
  for (const OptionRow& r : solver_option_rows()) {
    EXPECT_NE(r.families, 0) << r.key << " is read by no family";
    for (const auto& [prefix, family] : tables)
      if (r.key.rfind(prefix, 0) == 0) {
        EXPECT_EQ(r.families, family_bit(family)) << r.key;
      }
  }
  EXPECT_EQ(find_solver_option("solver.name")->families, kAllFamilies);
  EXPECT_EQ(families_text(*find_solver_option("solver.name")), "every solver");
  EXPECT_TRUE(applies("solver.iterations", SolverFamily::PbdSeed));
  EXPECT_FALSE(applies("solver.iterations", SolverFamily::Global));
  EXPECT_TRUE(applies("solver.precision", SolverFamily::Xpbd));
  EXPECT_FALSE(applies("solver.precision", SolverFamily::PbdSeed));  // float by its D10
  EXPECT_TRUE(applies("solver.substeps", SolverFamily::Global));
  EXPECT_FALSE(applies("solver.contact_margin", SolverFamily::Reference));
  EXPECT_EQ(families_text(*find_solver_option("solver.threads")), "pbd, xpbd");
}

// validate(family) checks only the options that family reads: a bad value of another family's
// option is not its business (config/ warns when a scenario sets one); validate() checks every
// row.
TEST(SolverFamilies, ValidateChecksOnlyTheFamilysOptions) {
  SolverOptions o;
  o.seed_damping = 2.0;
  o.global_tolerance = -1.0;
  o.seed_dynamic_inverse_mass = o.seed_graded_inverse_mass = true;
  EXPECT_EQ(o.validate(SolverFamily::Xpbd), "");
  EXPECT_EQ(o.validate(SolverFamily::PbdSeed), "solver.seed.damping = 2 is above the maximum 1");
  EXPECT_EQ(o.validate(), "solver.seed.damping = 2 is above the maximum 1");
  o.seed_damping = 0.5;
  EXPECT_NE(o.validate(SolverFamily::PbdSeed).find("choose one"), std::string::npos);
  EXPECT_EQ(o.validate(SolverFamily::Global), "solver.global.tolerance = -1 must be greater than 0");
  o.global_tolerance = 1e-9;
  EXPECT_EQ(o.validate(SolverFamily::Global), "");
  EXPECT_NE(o.validate().find("choose one"), std::string::npos);
  o.seed_dynamic_inverse_mass = false;
  o.iterations = 0;
  EXPECT_EQ(o.validate(SolverFamily::Reference), "");  // ref-* do not read solver.iterations
  EXPECT_EQ(o.validate(SolverFamily::Pbd), "solver.iterations = 0 is below the minimum 1");
  EXPECT_EQ(std::string(to_string(SolverFamily::Reference)), "ref-*");
}

}  // namespace
}  // namespace pbdbench::test
