// experiments/expression: parsing, precedence, NaN handling, reductions and the errors.
#include <gtest/gtest.h>

#include <cmath>
#include <limits>
#include <map>

#include "experiments/expression.hpp"

namespace pbdbench::experiments {
namespace {

constexpr double kNaN = std::numeric_limits<double>::quiet_NaN();

class MapScope final : public Scope {
 public:
  std::map<std::string, double> scalars;
  std::map<std::string, std::vector<double>> rows;
  std::optional<double> scalar(const std::string& name) const override {
    auto it = scalars.find(name);
    if (it == scalars.end()) return std::nullopt;
    return it->second;
  }
  const std::vector<double>* series(const std::string& name) const override {
    auto it = rows.find(name);
    return it == rows.end() ? nullptr : &it->second;
  }
  const std::vector<double>* times() const override { return series("time"); }
};

double eval(const std::string& text, const Scope& scope = MapScope()) {
  return Expression(text).evaluate(scope);
}

TEST(Expression, ArithmeticAndPrecedence) {
  EXPECT_DOUBLE_EQ(eval("1 + 2 * 3"), 7.0);
  EXPECT_DOUBLE_EQ(eval("(1 + 2) * 3"), 9.0);
  EXPECT_DOUBLE_EQ(eval("2 ^ 3 ^ 2"), 512.0);  // right associative
  EXPECT_DOUBLE_EQ(eval("-2 ^ 2"), -4.0);
  EXPECT_DOUBLE_EQ(eval("10 / 4 - 1"), 1.5);
  EXPECT_DOUBLE_EQ(eval("0.98^50"), std::pow(0.98, 50));
  EXPECT_DOUBLE_EQ(eval("1e-3 * 2"), 2e-3);
}

TEST(Expression, ComparisonsAndLogic) {
  EXPECT_EQ(eval("1 < 2 and 3 >= 3"), 1.0);
  EXPECT_EQ(eval("1 < 2 and 3 > 3"), 0.0);
  EXPECT_EQ(eval("1 > 2 or 2 != 3"), 1.0);
  EXPECT_EQ(eval("not 1 == 1"), 0.0);
  EXPECT_EQ(eval("not (1 > 2) and 2 == 2"), 1.0);
  EXPECT_EQ(eval("1 + 1 == 2"), 1.0);  // arithmetic binds tighter than comparison
}

TEST(Expression, NaNMeansNotMeasured) {
  MapScope s;
  s.scalars = {{"a", kNaN}, {"b", 1.0}};
  EXPECT_TRUE(std::isnan(eval("a > 0", s)));
  EXPECT_TRUE(std::isnan(eval("a + b", s)));
  EXPECT_TRUE(std::isnan(eval("not a", s)));
  EXPECT_TRUE(std::isnan(eval("a > 0 and b > 0", s)));
  EXPECT_EQ(eval("a > 0 and b < 0", s), 0.0);  // false whatever a is
  EXPECT_EQ(eval("a > 0 or b > 0", s), 1.0);   // true whatever a is
  EXPECT_EQ(Expression("a > 0 and b > 0").nan_names(s), std::vector<std::string>{"a"});
}

TEST(Expression, Functions) {
  EXPECT_DOUBLE_EQ(eval("abs(-3)"), 3.0);
  EXPECT_DOUBLE_EQ(eval("sqrt(16)"), 4.0);
  EXPECT_DOUBLE_EQ(eval("log10(1000)"), 3.0);
  EXPECT_DOUBLE_EQ(eval("min(3, 1, 2)"), 1.0);
  EXPECT_DOUBLE_EQ(eval("max(3, 1, 2)"), 3.0);
}

TEST(Expression, ReductionsSkipTheInitialRowAndNaN) {
  MapScope s;
  s.rows["time"] = {0.0, 1.0, 2.0, 3.0, 4.0};
  s.rows["e"] = {100.0, 1.0, kNaN, 3.0, -5.0};
  EXPECT_DOUBLE_EQ(eval("initial(e)", s), 100.0);
  EXPECT_DOUBLE_EQ(eval("final(e)", s), -5.0);
  EXPECT_DOUBLE_EQ(eval("max(e)", s), 3.0);  // the initial row is not a step
  EXPECT_DOUBLE_EQ(eval("min(e)", s), -5.0);
  EXPECT_DOUBLE_EQ(eval("maxabs(e)", s), 5.0);
  EXPECT_DOUBLE_EQ(eval("mean(e)", s), (1.0 + 3.0 - 5.0) / 3.0);
  EXPECT_DOUBLE_EQ(eval("sum(e)", s), -1.0);
  EXPECT_DOUBLE_EQ(eval("at(e, 3.5)", s), 3.0);
  EXPECT_DOUBLE_EQ(eval("mean_from(e, 3)", s), -1.0);
  EXPECT_DOUBLE_EQ(eval("max_from(e, 1.5)", s), 3.0);
  EXPECT_DOUBLE_EQ(eval("min_from(e, 0)", s), -5.0);
  EXPECT_TRUE(std::isnan(eval("mean_from(e, 10)", s)));  // no row in the window
  // The last w seconds, whatever the run's length: time >= 4 - 1.5.
  EXPECT_DOUBLE_EQ(eval("mean_last(e, 1.5)", s), -1.0);
  EXPECT_DOUBLE_EQ(eval("max_last(e, 2.5)", s), 3.0);
  EXPECT_DOUBLE_EQ(eval("min_last(e, 0.5)", s), -5.0);
  EXPECT_DOUBLE_EQ(eval("maxabs_last(e, 4)", s), 5.0);
  EXPECT_DOUBLE_EQ(eval("final(e) / initial(e) + 1", s), 0.95);
}

TEST(Expression, PeriodFromUpwardCrossings) {
  MapScope s;
  for (int i = 0; i <= 1000; ++i) {
    const double t = i * 0.01;
    s.rows["time"].push_back(t);
    s.rows["x"].push_back(3.0 + std::sin(2.0 * M_PI * t / 0.7));  // period 0.7 s about a mean of 3
  }
  EXPECT_NEAR(eval("period(x)", s), 0.7, 1e-3);
  EXPECT_NEAR(eval("period_from(x, 5)", s), 0.7, 1e-3);
  EXPECT_NEAR(eval("period_last(x, 5)", s), 0.7, 1e-3);
  s.rows["flat"] = std::vector<double>(1001, 1.0);
  EXPECT_TRUE(std::isnan(eval("period(flat)", s)));
}

TEST(Expression, ListsTheNamesItUses) {
  const Expression e("mean_from(kinetic_energy, t0) > 2 * final(height_min) and exploded == 0");
  EXPECT_EQ(e.series_names(), (std::vector<std::string>{"kinetic_energy", "height_min"}));
  EXPECT_EQ(e.scalar_names(), (std::vector<std::string>{"t0", "exploded"}));
}

TEST(Expression, BadTextIsRefusedWithTheColumn) {
  auto message = [](const std::string& text) {
    try {
      Expression e(text);
    } catch (const std::invalid_argument& err) {
      return std::string(err.what());
    }
    return std::string("no error");
  };
  EXPECT_NE(message("1 +").find("column 4"), std::string::npos) << message("1 +");
  EXPECT_NE(message("(1 + 2").find("expected ')'"), std::string::npos);
  EXPECT_NE(message("frobnicate(x)").find("unknown function 'frobnicate'"), std::string::npos);
  EXPECT_NE(message("final(1)").find("takes the name of a series"), std::string::npos);
  EXPECT_NE(message("at(e)").find("takes the name of a series and 1 number"), std::string::npos);
  EXPECT_NE(message("1 < 2 < 3").find("comparisons do not chain"), std::string::npos);
  EXPECT_NE(message("a and or 1").find("where a value was expected"), std::string::npos);
  EXPECT_NE(message("abs(1, 2)").find("takes one argument"), std::string::npos);
}

std::string refusal(const std::string& text) {
  try {
    Expression e(text);
  } catch (const std::invalid_argument& err) {
    return err.what();
  }
  return "no error";
}

std::string repeat(const std::string& s, int n) {
  std::string out;
  for (int k = 0; k < n; ++k) out += s;
  return out;
}

// Inputs that crashed the parser (a stack overflow in its recursion, or in the evaluator's and
// the tree's destructor's over a chain) are refused at once, with the column, in a short message.
TEST(Expression, TextsBeyondTheLimitsAreRefusedNotCrashed) {
  const std::vector<std::string> huge = {
      repeat("(", 10000) + "1" + repeat(")", 10000),  // 10,000 nested parentheses
      "1" + repeat(" + 1", 100000),                   // a 100,000-term sum
      "1" + repeat(" and 1", 1000000),                // a million-term and
      repeat("-", 1000000) + "1",                     // a million unary operators
  };
  for (const std::string& text : huge) {
    const std::string e = refusal(text);
    EXPECT_NE(e.find("characters long; at most 10000 are taken"), std::string::npos) << e.substr(0, 300);
    EXPECT_NE(e.find("at column 10001"), std::string::npos) << e.substr(0, 300);
    EXPECT_LT(e.size(), 300u);  // an excerpt, not the text
  }
  // Within the length, the depth: nesting, chains and unary runs of more than 200 levels.
  const int over = kMaxExpressionDepth + 1;
  for (const std::string& text : {repeat("(", over) + "1" + repeat(")", over), "1" + repeat("+1", over),
                                  "1" + repeat(" and 1", over), repeat("-", over) + "1", repeat("not ", over) + "1",
                                  repeat("abs(", over) + "1" + repeat(")", over), "2" + repeat("^2", over)}) {
    const std::string e = refusal(text);
    EXPECT_NE(e.find("nested more than 200 levels deep"), std::string::npos) << text.substr(0, 40) << ": " << e;
    EXPECT_NE(e.find("at column "), std::string::npos) << e;
  }
  // The deepest allowed is taken and evaluates.
  const int most = kMaxExpressionDepth;
  EXPECT_EQ(eval(repeat("(", most) + "1" + repeat(")", most)), 1.0);
  EXPECT_EQ(eval("0" + repeat("+1", most - 1)), most - 1.0);
  EXPECT_EQ(eval(repeat("-", most - 1) + "1"), -1.0);
}

TEST(Expression, NumbersAreDecimalOnly) {
  EXPECT_DOUBLE_EQ(eval("1.5e3 + .5 + 1. + 2E+1 + 1e-2"), 1521.51);
  EXPECT_NE(refusal("0x10 > 1").find("hexadecimal is not taken"), std::string::npos) << refusal("0x10 > 1");
  EXPECT_NE(refusal("0X1p4").find("column 1"), std::string::npos);
  EXPECT_NE(refusal("2a + 1").find("'2a' is not a number"), std::string::npos) << refusal("2a + 1");
  EXPECT_NE(refusal("1e999 > 1").find("out of the range of a double"), std::string::npos) << refusal("1e999 > 1");
  EXPECT_NE(refusal("1 + 1e").find("'1e' is not a number"), std::string::npos) << refusal("1 + 1e");
  EXPECT_EQ(refusal("inf > 1"), "no error");  // a name, unknown when evaluated: not infinity
  EXPECT_THROW(eval("inf > 1"), std::invalid_argument);
}

// ±inf is no measurement: 1/0 > 5 would otherwise hold and decide a part.
TEST(Expression, NonFiniteValuesAreNaNAndSayWhy) {
  MapScope s;
  s.scalars = {{"a", 1.0}, {"zero", 0.0}, {"big", std::numeric_limits<double>::infinity()}};
  const Expression::Checked c = Expression("a / zero > 5").evaluate_checked(s);
  EXPECT_TRUE(std::isnan(c.value));
  EXPECT_EQ(c.nonfinite, "`a / zero` (column 1) is inf (of 1 / 0)");
  EXPECT_TRUE(std::isnan(eval("1/0 > 5")));
  EXPECT_TRUE(std::isnan(eval("-1/0 < 5")));
  EXPECT_EQ(Expression("0/0 == 0").evaluate_checked(s).nonfinite, "`0/0` (column 1) is NaN (of 0 / 0)");
  EXPECT_NE(Expression("log10(zero) < 1").evaluate_checked(s).nonfinite.find("`log10(zero)` (column 1) is -inf"),
            std::string::npos);
  EXPECT_NE(Expression("sqrt(0 - a) < 1").evaluate_checked(s).nonfinite.find("is NaN (of -1)"), std::string::npos);
  EXPECT_NE(Expression("10^400 > 1").evaluate_checked(s).nonfinite.find("is inf"), std::string::npos);
  EXPECT_NE(Expression("1 + (big > 2)").evaluate_checked(s).nonfinite.find("`big` (column 6) is inf"),
            std::string::npos);
  s.rows["x"] = {0.0, 1.0, std::numeric_limits<double>::infinity()};
  EXPECT_NE(Expression("final(x) > 1").evaluate_checked(s).nonfinite.find("`final(x)` (column 1) is inf"),
            std::string::npos);
  // A non-finite step that `and` makes irrelevant is no reason; a NaN input is not non-finite.
  const Expression::Checked dropped = Expression("zero > 0 and 1/0 > 5").evaluate_checked(s);
  EXPECT_EQ(dropped.value, 0.0);
  EXPECT_EQ(dropped.nonfinite, "");
  s.scalars["m"] = kNaN;
  EXPECT_EQ(Expression("m > 1").evaluate_checked(s).nonfinite, "");
}

TEST(Expression, UnknownNamesAreErrorsWhenEvaluated) {
  MapScope s;
  EXPECT_THROW(eval("missing > 1", s), std::invalid_argument);
  EXPECT_THROW(eval("final(missing)", s), std::invalid_argument);
}

}  // namespace
}  // namespace pbdbench::experiments
