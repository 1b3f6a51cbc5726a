// The small expression language of the claim files (claims/experiments/*.toml): a measure's
// `value` (over one run's series and attributes) and a part's `rule` (over measures).
//
//   final(penetration_max) > 0.0005                 1 or 0 for one trial
//   mean_from(velocity_hf_rms, 2.0)                 a series reduced over t >= 2 s
//   rate_sequential >= 0.9 and rate_grouped <= 0.1  a rule over measures
//
// Grammar (usual precedence, lowest first): `or`, `and`, `not`, comparisons (< <= > >= == !=),
// + -, * /, unary -, ^ (right associative); numbers (1, 0.5, 1e-3), names ([A-Za-z_][A-Za-z0-9_.]*),
// calls name(arg, ...), parentheses. Truth is 1, falsehood 0; a condition is true when it is
// non-zero.
//
// NaN is "not measured": arithmetic, comparisons and logic with a NaN operand give NaN (so a rule
// that touches a NaN measure has no verdict rather than a false one), except that `and` with a
// false operand is false and `or` with a true operand is true.
//
// Functions of numbers: abs(x), sqrt(x), log10(x), min(a, b, ...), max(a, b, ...).
// Reductions of a series (the first argument is the name of a series of the run; a width-3
// series is addressed by component, tip_displacement.y):
//   initial(s)           the first row (the initial state)
//   final(s)             the last row
//   max(s), min(s), mean(s), sum(s), maxabs(s)   over the rows after the initial one (the steps)
//   at(s, t)             the row with the largest time <= t
//   max_from(s, t0), min_from(s, t0), mean_from(s, t0), maxabs_from(s, t0)   over steps with time >= t0
//   max_last(s, w), min_last(s, w), mean_last(s, w), maxabs_last(s, w), period_last(s, w)
//                        the same over the last w seconds (time >= final time - w), whatever
//                        the run's length (a quick tier's shorter runs read the same window)
//   period(s), period_from(s, t0)   the mean time between successive upward crossings of the
//                        series' mean (over the steps, or those with time >= t0), crossings
//                        interpolated linearly; NaN with fewer than two crossings
// A reduction skips NaN rows; over no finite row it gives NaN. (max/min with two or more numeric
// arguments are the functions of numbers.)
//
// Numbers are decimal (1, 0.5, .5, 1e-3, 2E+4); 0x10, 1e999 and a number run into a name (2a)
// are refused.
//
// Non-finite values are not measurements: an operation that gives ±inf or NaN from finite
// operands (1/0, 0/0, log10(0), sqrt(-1), 10^400), a name whose value is ±inf and a reduction
// that gives ±inf (final(s) of a series that ends at inf) give NaN, so that a rule over them has
// no verdict rather than the one ±inf would decide; evaluate_checked() says which operation it was.
//
// Limits: a text longer than kMaxExpressionLength characters, or nested deeper than
// kMaxExpressionDepth levels, is refused with the column where the limit was crossed. Parsing,
// evaluating and freeing the tree recurse over its depth, so a bound on the depth is what keeps
// every input from exhausting the stack.
#pragma once

#include <cstddef>
#include <functional>
#include <memory>
#include <optional>
#include <span>
#include <string>
#include <vector>

namespace pbdbench::experiments {

// The longest text a measure's value or a rule may have. The longest in claims/ and
// reproductions/ is 783 characters (xpbd2016_chain_force.toml, a max() of twenty ratios); ten
// thousand leaves room for any rule a person writes and keeps a refused one's parse instant.
inline constexpr std::size_t kMaxExpressionLength = 10000;

// The deepest nesting: each parenthesis, call, unary operator (-, not) and each operator of a
// chain (a + b + c is two levels: the tree is built left to right) counts one level. The deepest
// in claims/ and reproductions/ is far below it; 200 levels of the recursive parser and evaluator
// use well under a megabyte of stack, also under AddressSanitizer.
inline constexpr int kMaxExpressionDepth = 200;

// What a name stands for when an expression is evaluated.
class Scope {
 public:
  virtual ~Scope() = default;
  // The value of a plain name, or nullopt when the scope has no such scalar.
  virtual std::optional<double> scalar(const std::string& name) const = 0;
  // The rows of a series (one value per row), or nullptr when there is no such series.
  virtual const std::vector<double>* series(const std::string& name) const = 0;
  // The time of each row (s), for the reductions that take a time; nullptr outside a run.
  virtual const std::vector<double>* times() const = 0;
};

struct Node;  // the parsed tree

class Expression {
 public:
  // Parses `text`; throws std::invalid_argument with the column and what was expected.
  explicit Expression(const std::string& text);
  ~Expression();
  Expression(const Expression&);
  Expression& operator=(const Expression&);
  Expression(Expression&&) noexcept;
  Expression& operator=(Expression&&) noexcept;

  const std::string& text() const { return text_; }

  // Names used as scalars, and names used as series arguments of reductions (each once, in
  // order of appearance), so that a file can be checked before anything runs.
  std::vector<std::string> scalar_names() const;
  std::vector<std::string> series_names() const;

  // Evaluates; throws std::invalid_argument naming the name the scope lacks. A non-finite
  // value is NaN (see above).
  double evaluate(const Scope& scope) const;

  // As evaluate(), with why the value is NaN when something non-finite made it so: the first
  // such operation or name, "`a / b` is inf (a = 1, b = 0)"-like text; "" otherwise (a NaN
  // input, for which nan_names() says which).
  struct Checked {
    double value = 0.0;
    std::string nonfinite;
  };
  Checked evaluate_checked(const Scope& scope) const;

  // The names whose values are NaN in `scope` (used to say why a rule has no verdict).
  std::vector<std::string> nan_names(const Scope& scope) const;

 private:
  std::string text_;
  std::shared_ptr<const Node> root_;
};

}  // namespace pbdbench::experiments
