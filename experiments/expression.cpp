#include "experiments/expression.hpp"

#include <algorithm>
#include <cctype>
#include <charconv>
#include <cmath>
#include <limits>
#include <set>
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
  std::size_t begin = 0, end = 0;  // the node's characters in the expression: [begin, end)
  int depth = 1;                   // levels of the tree from this node down (a leaf is 1)
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

// At most `width` characters of `text` around [begin, end), with "..." where it was cut, so that
// a message about a long expression stays one line.
std::string excerpt(const std::string& text, std::size_t begin, std::size_t end, std::size_t width = 60) {
  begin = std::min(begin, text.size());
  end = std::clamp(end, begin, text.size());
  if (end - begin > width) return text.substr(begin, width / 2) + "..." + text.substr(end - width / 2, width / 2);
  const std::size_t room = (width - (end - begin)) / 2;
  const std::size_t from = begin > room ? begin - room : 0;
  const std::size_t to = std::min(text.size(), end + room);
  return (from > 0 ? "..." : "") + text.substr(from, to - from) + (to < text.size() ? "..." : "");
}

// `s` cut to at most `width` characters, its middle replaced by "...".
std::string clip(const std::string& s, std::size_t width = 60) {
  return s.size() <= width ? s : s.substr(0, width / 2) + "..." + s.substr(s.size() - width / 2);
}

bool is_name_char(char c) { return std::isalnum(static_cast<unsigned char>(c)) || c == '_' || c == '.'; }

class Parser {
 public:
  explicit Parser(const std::string& text) : s_(text) {}

  NodePtr parse() {
    if (s_.size() > kMaxExpressionLength) {
      pos_ = kMaxExpressionLength;
      fail("the expression is " + std::to_string(s_.size()) + " characters long; at most " +
           std::to_string(kMaxExpressionLength) + " are taken");
    }
    NodePtr n = parse_or();
    skip_space();
    if (pos_ != s_.size()) fail("unexpected '" + s_.substr(pos_, 1) + "'");
    return n;
  }

 private:
  [[noreturn]] void fail(const std::string& what) const {
    const std::string where = s_.size() <= 80 ? "in '" + s_ + "'"
                                              : "in '" + excerpt(s_, pos_, pos_ + 1) + "'";
    throw std::invalid_argument(where + " at column " + std::to_string(pos_ + 1) + ": " + what);
  }
  [[noreturn]] void too_deep() const {
    fail("nested more than " + std::to_string(kMaxExpressionDepth) +
         " levels deep (each parenthesis, call, unary operator and each operator of a chain such as "
         "a + b + c is a level)");
  }
  // One level of the parser's recursion (a parenthesis, a call's arguments, a unary operator, an
  // exponent): refused beyond kMaxExpressionDepth before the stack is at risk.
  class Level {
   public:
    explicit Level(Parser& p) : p_(p) {
      if (++p_.depth_ > kMaxExpressionDepth) p_.too_deep();
    }
    ~Level() { --p_.depth_; }
    Level(const Level&) = delete;
    Level& operator=(const Level&) = delete;

   private:
    Parser& p_;
  };

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
  NodePtr binary(const std::string& op, NodePtr a, NodePtr b) {
    auto n = std::make_shared<Node>();
    n->kind = Node::Kind::Binary;
    n->text = op;
    n->begin = a->begin;
    n->end = b->end;
    n->depth = 1 + std::max(a->depth, b->depth);
    if (n->depth > kMaxExpressionDepth) too_deep();
    n->args = {std::move(a), std::move(b)};
    return n;
  }
  NodePtr unary(const std::string& op, std::size_t begin, NodePtr a) {
    auto n = std::make_shared<Node>();
    n->kind = Node::Kind::Unary;
    n->text = op;
    n->begin = begin;
    n->end = a->end;
    n->depth = 1 + a->depth;
    if (n->depth > kMaxExpressionDepth) too_deep();
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
    skip_space();
    const std::size_t begin = pos_;
    if (accept_word("not")) {
      const Level level(*this);
      return unary("not", begin, parse_not());
    }
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
    skip_space();
    const std::size_t begin = pos_;
    if (accept("-")) {
      const Level level(*this);
      return unary("-", begin, parse_unary());
    }
    return parse_power();
  }
  NodePtr parse_power() {
    NodePtr base = parse_atom();
    if (accept("^")) {
      const Level level(*this);
      return binary("^", base, parse_unary());
    }
    return base;
  }
  // A decimal number: digits, an optional fraction, an optional exponent. Read here rather than
  // by strtod, which would also take 0x1p4, inf and nan (and reads to the end of the text).
  NodePtr parse_number() {
    const std::size_t begin = pos_;
    std::size_t p = pos_, digits = 0;
    auto run = [&] {
      std::size_t k = 0;
      while (p < s_.size() && std::isdigit(static_cast<unsigned char>(s_[p]))) ++p, ++k;
      return k;
    };
    digits += run();
    if (p < s_.size() && s_[p] == '.') {
      ++p;
      digits += run();
    }
    if (digits == 0) fail("expected a number, a name or '('");
    if (p < s_.size() && (s_[p] == 'e' || s_[p] == 'E')) {
      std::size_t q = p + 1;
      if (q < s_.size() && (s_[q] == '+' || s_[q] == '-')) ++q;
      if (q < s_.size() && std::isdigit(static_cast<unsigned char>(s_[q]))) {
        p = q;
        run();
      }
    }
    if (p < s_.size() && is_name_char(s_[p])) {
      std::size_t q = p;
      while (q < s_.size() && is_name_char(s_[q])) ++q;
      fail("'" + clip(s_.substr(begin, q - begin)) + "' is not a number: numbers are decimal (12, 0.5, 1e-3)" +
           (s_.compare(begin, 2, "0x") == 0 || s_.compare(begin, 2, "0X") == 0 ? "; hexadecimal is not taken" : ""));
    }
    double value = 0.0;
    const auto [end, ec] = std::from_chars(s_.data() + begin, s_.data() + p, value);
    if (ec != std::errc() || end != s_.data() + p)
      fail("'" + clip(s_.substr(begin, p - begin)) + "' is out of the range of a double (about 1e-308 to 1e308)");
    pos_ = p;
    auto n = std::make_shared<Node>();
    n->number = value;
    n->begin = begin;
    n->end = p;
    return n;
  }
  NodePtr parse_atom() {
    skip_space();
    if (pos_ >= s_.size()) fail("expected a number, a name or '('");
    const char c = s_[pos_];
    const std::size_t begin = pos_;
    if (c == '(') {
      const Level level(*this);
      ++pos_;
      NodePtr inner = parse_or();
      if (!accept(")")) fail("expected ')'");
      auto n = std::make_shared<Node>(*inner);  // the same node, quoted with its parentheses
      n->begin = begin;
      n->end = pos_;
      return n;
    }
    if (std::isdigit(static_cast<unsigned char>(c)) || c == '.') return parse_number();
    if (std::isalpha(static_cast<unsigned char>(c)) || c == '_') {
      while (pos_ < s_.size() && is_name_char(s_[pos_])) ++pos_;
      const std::string name = s_.substr(begin, pos_ - begin);
      for (const char* reserved : {"and", "or", "not"})
        if (name == reserved) fail("'" + name + "' where a value was expected");
      auto n = std::make_shared<Node>();
      n->text = name;
      n->begin = begin;
      n->end = pos_;
      if (accept("(")) {
        const Level level(*this);
        n->kind = Node::Kind::Call;
        if (!accept(")")) {
          do {
            n->args.push_back(parse_or());
            n->depth = std::max(n->depth, 1 + n->args.back()->depth);
            if (n->depth > kMaxExpressionDepth) too_deep();
          } while (accept(","));
          if (!accept(")")) fail("expected ',' or ')' in the arguments of " + name);
        }
        check_call(*n);
        n->end = pos_;
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
      fail("unknown function '" + clip(call.text) + "' (known: " + known + ")");
    }
    const bool variadic = call.text == "min" || call.text == "max";
    if (variadic ? call.args.size() < 2 : call.args.size() != 1)
      fail(call.text + "() takes " + (variadic ? "two or more arguments" : "one argument"));
  }

  std::string s_;
  size_t pos_ = 0;
  int depth_ = 0;  // levels of recursion now open
};

// The names in order of first appearance; `seen` keeps the look-up linear in the names.
struct Names {
  std::vector<std::string> scalars, series;
  std::set<std::string> seen_scalars, seen_series;
};
void collect(const Node& n, Names& out) {
  if (n.kind == Node::Kind::Name && out.seen_scalars.insert(n.text).second) out.scalars.push_back(n.text);
  if (n.kind == Node::Kind::Call && is_reduction_call(n)) {
    if (out.seen_series.insert(n.args[0]->text).second) out.series.push_back(n.args[0]->text);
    for (size_t i = 1; i < n.args.size(); ++i) collect(*n.args[i], out);
    return;
  }
  for (const NodePtr& a : n.args) collect(*a, out);
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

std::string value_text(double v) {
  if (std::isnan(v)) return "NaN";
  if (std::isinf(v)) return v > 0 ? "inf" : "-inf";
  char buf[32];
  const auto r = std::to_chars(buf, buf + sizeof buf, v);
  return std::string(buf, r.ptr);
}

// One evaluation: the scope, the text (to quote), and the first non-finite value met.
struct Evaluator {
  const Scope& scope;
  const std::string& text;
  std::string why;

  // A non-finite `v` made by node `n` from finite inputs (`inputs`: "1, 0"), turned into NaN.
  double nonfinite(const Node& n, double v, const std::string& inputs) {
    if (why.empty())
      why = "`" + clip(text.substr(n.begin, n.end - n.begin)) + "` (column " + std::to_string(n.begin + 1) + ") is " +
            value_text(v) + (inputs.empty() ? "" : " (of " + inputs + ")");
    return kNaN;
  }

  double eval(const Node& n) {
    switch (n.kind) {
      case Node::Kind::Number:
        return n.number;
      case Node::Kind::Name: {
        const std::optional<double> v = scope.scalar(n.text);
        if (!v) throw std::invalid_argument("no value named '" + n.text + "'");
        if (std::isinf(*v)) return nonfinite(n, *v, "");
        return *v;
      }
      case Node::Kind::Unary: {
        const double a = eval(*n.args[0]);
        if (std::isnan(a)) return kNaN;
        return n.text == "-" ? -a : (a == 0.0 ? 1.0 : 0.0);
      }
      case Node::Kind::Binary: {
        const std::string& op = n.text;
        const double a = eval(*n.args[0]);
        const double b = eval(*n.args[1]);
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
        if (op == "<") return a < b ? 1.0 : 0.0;
        if (op == "<=") return a <= b ? 1.0 : 0.0;
        if (op == ">") return a > b ? 1.0 : 0.0;
        if (op == ">=") return a >= b ? 1.0 : 0.0;
        if (op == "==") return a == b ? 1.0 : 0.0;
        if (op == "!=") return a != b ? 1.0 : 0.0;
        double r = 0.0;
        if (op == "+") r = a + b;
        else if (op == "-") r = a - b;
        else if (op == "*") r = a * b;
        else if (op == "/") r = a / b;
        else r = std::pow(a, b);  // "^"
        if (!std::isfinite(r)) return nonfinite(n, r, value_text(a) + " " + op + " " + value_text(b));
        return r;
      }
      case Node::Kind::Call: {
        if (is_reduction_call(n)) {
          const std::string& name = n.args[0]->text;
          const std::vector<double>* rows = scope.series(name);
          if (rows == nullptr) throw std::invalid_argument("no series named '" + name + "'");
          const double arg = n.args.size() > 1 ? eval(*n.args[1]) : 0.0;
          const double r = reduce(n.text, *rows, scope.times(), arg, name);
          if (std::isinf(r)) return nonfinite(n, r, "");
          return r;
        }
        std::vector<double> v;
        for (const NodePtr& a : n.args) v.push_back(eval(*a));
        if (std::any_of(v.begin(), v.end(), [](double x) { return std::isnan(x); })) return kNaN;
        double r = 0.0;
        if (n.text == "abs") r = std::abs(v[0]);
        else if (n.text == "sqrt") r = std::sqrt(v[0]);
        else if (n.text == "log10") r = std::log10(v[0]);
        else if (n.text == "min") r = *std::min_element(v.begin(), v.end());
        else r = *std::max_element(v.begin(), v.end());  // "max"
        if (!std::isfinite(r)) return nonfinite(n, r, value_text(v[0]));
        return r;
      }
    }
    return kNaN;
  }
};

}  // namespace

Expression::Expression(const std::string& text) : text_(text), root_(Parser(text).parse()) {}
Expression::~Expression() = default;
Expression::Expression(const Expression&) = default;
Expression& Expression::operator=(const Expression&) = default;
Expression::Expression(Expression&&) noexcept = default;
Expression& Expression::operator=(Expression&&) noexcept = default;

std::vector<std::string> Expression::scalar_names() const {
  Names names;
  collect(*root_, names);
  return names.scalars;
}

std::vector<std::string> Expression::series_names() const {
  Names names;
  collect(*root_, names);
  return names.series;
}

double Expression::evaluate(const Scope& scope) const { return evaluate_checked(scope).value; }

Expression::Checked Expression::evaluate_checked(const Scope& scope) const {
  Evaluator e{scope, text_, {}};
  Checked out;
  out.value = e.eval(*root_);
  // A non-finite step that `and`/`or` made irrelevant (0 and 1/0 is false) is no reason.
  if (std::isnan(out.value)) out.nonfinite = std::move(e.why);
  return out;
}

std::vector<std::string> Expression::nan_names(const Scope& scope) const {
  std::vector<std::string> out;
  for (const std::string& name : scalar_names()) {
    const std::optional<double> v = scope.scalar(name);
    if (v && std::isnan(*v)) out.push_back(name);
  }
  return out;
}

}  // namespace pbdbench::experiments
