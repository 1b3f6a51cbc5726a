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
#pragma once

#include <functional>
#include <memory>
#include <optional>
#include <span>
#include <string>
#include <vector>

namespace pbdbench::experiments {

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

  // Evaluates; throws std::invalid_argument naming the name the scope lacks.
  double evaluate(const Scope& scope) const;

  // The names whose values are NaN in `scope` (used to say why a rule has no verdict).
  std::vector<std::string> nan_names(const Scope& scope) const;

 private:
  std::string text_;
  std::shared_ptr<const Node> root_;
};

}  // namespace pbdbench::experiments
