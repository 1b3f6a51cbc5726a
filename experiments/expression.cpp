#include "experiments/expression.hpp"

#include <algorithm>
#include <cctype>
#include <cmath>
#include <limits>
#include <stdexcept>

namespace pbdbench::experiments {

namespace {
constexpr double kNaN = std::numeric_limits<double>::quiet_NaN();
}

// A node of the parsed tree: a number, a name, an operator or a call.
struct Node {
  enum class Kind { Number, Name, Unary, Binary, Call } kind = Kind::Number;
  double number = 0.0;
  std::string text;  // the name, the operator ("-", "not", "+", "and", "<=", ...), the function
  std::vector<std::shared_ptr<const Node>> args;
};

namespace {

using NodePtr = std::shared_ptr<const Node>;

// Reductions of a series, and how many numeric arguments follow the series.
struct Reduction {
  const char* name;
  int extra;  // numbers after the series argument
};
constexpr Reduction kReductions[] = {
    {"initial", 0},  {"final", 0},    {"max", 0},      {"min", 0},      {"mean", 0},
    {"sum", 0},      {"maxabs", 0},   {"at", 1},       {"max_from", 1}, {"min_from", 1},
    {"mean_from", 1}, {"maxabs_from", 1}, {"period", 0},  {"period_from", 1},
    {"max_last", 1}, {"min_last", 1}, {"mean_last", 1}, {"maxabs_last", 1}, {"period_last", 1},
};
constexpr const char* kNumericFunctions[] = {"abs", "sqrt", "log10", "min", "max"};

const Reduction* find_reduction(const std::string& name) {
  for (const Reduction& r : kReductions)
    if (name == r.name) return &r;
  return nullptr;
}
bool is_numeric_function(const std::string& name) {
  return std::find_if(std::begin(kNumericFunctions), std::end(kNumericFunctions),
                      [&](const char* f) { return name == f; }) != std::end(kNumericFunctions);
}
// max(s) and min(s) with a single name argument reduce a series; with numbers they compare.
bool is_reduction_call(const Node& call) {
  const Reduction* r = find_reduction(call.text);
  if (r == nullptr) return false;
  if ((call.text == "max" || call.text == "min") && call.args.size() != 1) return false;
  return call.args.size() == static_cast<size_t>(1 + r->extra) && !call.args.empty() &&
         call.args[0]->kind == Node::Kind::Name;
}

class Parser {
 public:
  explicit Parser(const std::string& text) : s_(text) {}

  NodePtr parse() {
    NodePtr n = parse_or();
    skip_space();
    if (pos_ != s_.size()) fail("unexpected '" + s_.substr(pos_, 1) + "'");
    return n;
  }

 private:
  [[noreturn]] void fail(const std::string& what) const {
    throw std::invalid_argument("in '" + s_ + "' at column " + std::to_string(pos_ + 1) + ": " +
                                what);
  }
  void skip_space() {
    while (pos_ < s_.size() && std::isspace(static_cast<unsigned char>(s_[pos_]))) ++pos_;
  }
  bool word_ahead(const char* w) {
    skip_space();
    const size_t n = std::char_traits<char>::length(w);
    if (s_.compare(pos_, n, w) != 0) return false;
    const size_t end = pos_ + n;
    return end == s_.size() || !(std::isalnum(static_cast<unsigned char>(s_[end])) || s_[end] == '_');
  }
  bool accept_word(const char* w) {
    if (!word_ahead(w)) return false;
    pos_ += std::char_traits<char>::length(w);
    return true;
  }
  bool accept(const char* op) {
    skip_space();
    const size_t n = std::char_traits<char>::length(op);
    if (s_.compare(pos_, n, op) != 0) return false;
    pos_ += n;
    return true;
  }
  static NodePtr binary(const std::string& op, NodePtr a, NodePtr b) {
    auto n = std::make_shared<Node>();
    n->kind = Node::Kind::Binary;
    n->text = op;
    n->args = {std::move(a), std::move(b)};
    return n;
  }
  static NodePtr unary(const std::string& op, NodePtr a) {
    auto n = std::make_shared<Node>();
    n->kind = Node::Kind::Unary;
    n->text = op;
    n->args = {std::move(a)};
    return n;
  }

  NodePtr parse_or() {
    NodePtr n = parse_and();
    while (accept_word("or")) n = binary("or", n, parse_and());
    return n;
  }
  NodePtr parse_and() {
    NodePtr n = parse_not();
    while (accept_word("and")) n = binary("and", n, parse_not());
    return n;
  }
  NodePtr parse_not() {
    if (accept_word("not")) return unary("not", parse_not());
    return parse_comparison();
  }
  NodePtr parse_comparison() {
    NodePtr n = parse_sum();
    for (const char* op : {"<=", ">=", "==", "!=", "<", ">"}) {
      if (accept(op)) {
        NodePtr rhs = parse_sum();
        skip_space();
        for (const char* again : {"<", ">", "=", "!"})
          if (pos_ < s_.size() && s_[pos_] == again[0]) fail("comparisons do not chain");
        return binary(op, n, rhs);
      }
    }
    return n;
  }
  NodePtr parse_sum() {
    NodePtr n = parse_product();
    for (;;) {
      if (accept("+")) n = binary("+", n, parse_product());
      else if (accept("-")) n = binary("-", n, parse_product());
      else return n;
    }
  }
  NodePtr parse_product() {
    NodePtr n = parse_unary();
    for (;;) {
      if (accept("*")) n = binary("*", n, parse_unary());
      else if (accept("/")) n = binary("/", n, parse_unary());
      else return n;
    }
  }
  NodePtr parse_unary() {
    if (accept("-")) return unary("-", parse_unary());
    return parse_power();
  }
  NodePtr parse_power() {
    NodePtr base = parse_atom();
    if (accept("^")) return binary("^", base, parse_unary());
    return base;
  }
  NodePtr parse_atom() {
    skip_space();
    if (pos_ >= s_.size()) fail("expected a number, a name or '('");
    const char c = s_[pos_];
    if (c == '(') {
      ++pos_;
      NodePtr n = parse_or();
      if (!accept(")")) fail("expected ')'");
      return n;
    }
    if (std::isdigit(static_cast<unsigned char>(c)) || c == '.') {
      size_t used = 0;
      double value = 0.0;
      try {
        value = std::stod(s_.substr(pos_), &used);
      } catch (const std::exception&) {
        fail("bad number");
      }
      pos_ += used;
      auto n = std::make_shared<Node>();
      n->number = value;
      return n;
    }
    if (std::isalpha(static_cast<unsigned char>(c)) || c == '_') {
      const size_t start = pos_;
      while (pos_ < s_.size() && (std::isalnum(static_cast<unsigned char>(s_[pos_])) ||
                                  s_[pos_] == '_' || s_[pos_] == '.'))
        ++pos_;
      const std::string name = s_.substr(start, pos_ - start);
      for (const char* reserved : {"and", "or", "not"})
        if (name == reserved) fail("'" + name + "' where a value was expected");
      auto n = std::make_shared<Node>();
      n->text = name;
      if (accept("(")) {
        n->kind = Node::Kind::Call;
        if (!accept(")")) {
          do n->args.push_back(parse_or());
          while (accept(","));
          if (!accept(")")) fail("expected ',' or ')' in the arguments of " + name);
        }
        check_call(*n);
      } else {
        n->kind = Node::Kind::Name;
      }
      return n;
    }
    fail(std::string("unexpected '") + c + "'");
  }

  void check_call(const Node& call) {
    if (is_reduction_call(call)) return;
    if (const Reduction* r = find_reduction(call.text);
        r != nullptr && !((call.text == "max" || call.text == "min") && call.args.size() >= 2)) {
      fail(call.text + "() takes the name of a series" +
           (r->extra > 0 ? " and " + std::to_string(r->extra) + " number" : std::string()));
    }
    if (!is_numeric_function(call.text)) {
      std::string known;
      for (const Reduction& r : kReductions) known += std::string(known.empty() ? "" : ", ") + r.name;
      for (const char* f : kNumericFunctions) known += std::string(", ") + f;
      fail("unknown function '" + call.text + "' (known: " + known + ")");
    }
    const bool variadic = call.text == "min" || call.text == "max";
    if (variadic ? call.args.size() < 2 : call.args.size() != 1)
      fail(call.text + "() takes " + (variadic ? "two or more arguments" : "one argument"));
  }

  std::string s_;
  size_t pos_ = 0;
};

void collect(const Node& n, std::vector<std::string>& scalars, std::vector<std::string>& series) {
  auto add = [](std::vector<std::string>& v, const std::string& s) {
    if (std::find(v.begin(), v.end(), s) == v.end()) v.push_back(s);
  };
  if (n.kind == Node::Kind::Name) add(scalars, n.text);
  if (n.kind == Node::Kind::Call && is_reduction_call(n)) {
    add(series, n.args[0]->text);
    for (size_t i = 1; i < n.args.size(); ++i) collect(*n.args[i], scalars, series);
    return;
  }
  for (const NodePtr& a : n.args) collect(*a, scalars, series);
}

double reduce(const std::string& fn_in, const std::vector<double>& rows, const std::vector<double>* t,
              double arg_in, const std::string& name) {
  if (rows.empty()) return kNaN;
  // x_last(s, w) is x_from(s, t_final - w): the last w seconds of the run, whatever its length.
  std::string fn = fn_in;
  double arg = arg_in;
  if (fn.ends_with("_last")) {
    if (t == nullptr || t->size() != rows.size() || t->empty())
      throw std::invalid_argument(fn + "(" + name + ", ...) needs the times of a run");
    fn = fn.substr(0, fn.size() - 5) + "_from";
    arg = t->back() - arg;
  }
  if (fn == "initial") return rows.front();
  if (fn == "final") return rows.back();
  const bool timed = fn == "at" || fn.ends_with("_from") || fn == "period";
  if (timed && (t == nullptr || t->size() != rows.size()))
    throw std::invalid_argument(fn + "(" + name + ", ...) needs the times of a run");
  if (fn == "period" || fn == "period_from") {
    // Mean time between successive upward crossings of the mean of the rows considered (the
    // steps with time >= t0), each crossing time interpolated linearly.
    const double t0 = fn == "period" ? -1e300 : arg;
    double sum = 0.0;
    long n = 0;
    for (size_t i = 1; i < rows.size(); ++i)
      if ((*t)[i] >= t0 - 1e-12 && std::isfinite(rows[i])) sum += rows[i], ++n;
    if (n < 3) return kNaN;
    const double mean = sum / static_cast<double>(n);
    std::vector<double> up;
    for (size_t i = 2; i < rows.size(); ++i) {
      if ((*t)[i - 1] < t0 - 1e-12) continue;
      const double a = rows[i - 1] - mean, b = rows[i] - mean;
      if (a < 0.0 && b >= 0.0) up.push_back((*t)[i - 1] + ((*t)[i] - (*t)[i - 1]) * (-a) / (b - a));
    }
    if (up.size() < 2) return kNaN;
    return (up.back() - up.front()) / static_cast<double>(up.size() - 1);
  }
  if (fn == "at") {
    double v = kNaN;
    for (size_t i = 0; i < rows.size(); ++i)
      if ((*t)[i] <= arg + 1e-12) v = rows[i];
    return v;
  }
  double acc = 0.0, best = kNaN;
  long count = 0;
  const std::string base = fn.ends_with("_from") ? fn.substr(0, fn.size() - 5) : fn;
  for (size_t i = 1; i < rows.size(); ++i) {  // the steps, not the initial row
    if (timed && (*t)[i] < arg - 1e-12) continue;
    const double v = rows[i];
    if (!std::isfinite(v)) continue;
    ++count;
    if (base == "max") best = std::isnan(best) ? v : std::max(best, v);
    else if (base == "min") best = std::isnan(best) ? v : std::min(best, v);
    else if (base == "maxabs") best = std::isnan(best) ? std::abs(v) : std::max(best, std::abs(v));
    else acc += v;
  }
  if (count == 0) return kNaN;
  if (base == "mean") return acc / static_cast<double>(count);
  if (base == "sum") return acc;
  return best;
}

double eval(const Node& n, const Scope& scope) {
  switch (n.kind) {
    case Node::Kind::Number:
      return n.number;
    case Node::Kind::Name: {
      const std::optional<double> v = scope.scalar(n.text);
      if (!v) throw std::invalid_argument("no value named '" + n.text + "'");
      return *v;
    }
    case Node::Kind::Unary: {
      const double a = eval(*n.args[0], scope);
      if (std::isnan(a)) return kNaN;
      return n.text == "-" ? -a : (a == 0.0 ? 1.0 : 0.0);
    }
    case Node::Kind::Binary: {
      const std::string& op = n.text;
      const double a = eval(*n.args[0], scope);
      const double b = eval(*n.args[1], scope);
      if (op == "and") {
        if (a == 0.0 || b == 0.0) return 0.0;
        if (std::isnan(a) || std::isnan(b)) return kNaN;
        return 1.0;
      }
      if (op == "or") {
        if ((!std::isnan(a) && a != 0.0) || (!std::isnan(b) && b != 0.0)) return 1.0;
        if (std::isnan(a) || std::isnan(b)) return kNaN;
        return 0.0;
      }
      if (std::isnan(a) || std::isnan(b)) return kNaN;
      if (op == "+") return a + b;
      if (op == "-") return a - b;
      if (op == "*") return a * b;
      if (op == "/") return a / b;
      if (op == "^") return std::pow(a, b);
      if (op == "<") return a < b ? 1.0 : 0.0;
      if (op == "<=") return a <= b ? 1.0 : 0.0;
      if (op == ">") return a > b ? 1.0 : 0.0;
      if (op == ">=") return a >= b ? 1.0 : 0.0;
      if (op == "==") return a == b ? 1.0 : 0.0;
      return a != b ? 1.0 : 0.0;  // "!="
    }
    case Node::Kind::Call: {
      if (is_reduction_call(n)) {
        const std::string& name = n.args[0]->text;
        const std::vector<double>* rows = scope.series(name);
        if (rows == nullptr) throw std::invalid_argument("no series named '" + name + "'");
        const double arg = n.args.size() > 1 ? eval(*n.args[1], scope) : 0.0;
        return reduce(n.text, *rows, scope.times(), arg, name);
      }
      std::vector<double> v;
      for (const NodePtr& a : n.args) v.push_back(eval(*a, scope));
      if (std::any_of(v.begin(), v.end(), [](double x) { return std::isnan(x); })) return kNaN;
      if (n.text == "abs") return std::abs(v[0]);
      if (n.text == "sqrt") return std::sqrt(v[0]);
      if (n.text == "log10") return std::log10(v[0]);
      if (n.text == "min") return *std::min_element(v.begin(), v.end());
      return *std::max_element(v.begin(), v.end());  // "max"
    }
  }
  return kNaN;
}

}  // namespace

Expression::Expression(const std::string& text) : text_(text), root_(Parser(text).parse()) {}
Expression::~Expression() = default;
Expression::Expression(const Expression&) = default;
Expression& Expression::operator=(const Expression&) = default;
Expression::Expression(Expression&&) noexcept = default;
Expression& Expression::operator=(Expression&&) noexcept = default;

std::vector<std::string> Expression::scalar_names() const {
  std::vector<std::string> scalars, series;
  collect(*root_, scalars, series);
  return scalars;
}

std::vector<std::string> Expression::series_names() const {
  std::vector<std::string> scalars, series;
  collect(*root_, scalars, series);
  return series;
}

double Expression::evaluate(const Scope& scope) const { return eval(*root_, scope); }

std::vector<std::string> Expression::nan_names(const Scope& scope) const {
  std::vector<std::string> out;
  for (const std::string& name : scalar_names()) {
    const std::optional<double> v = scope.scalar(name);
    if (v && std::isnan(*v)) out.push_back(name);
  }
  return out;
}

}  // namespace pbdbench::experiments
