#include "turntable/modbus/expression.h"

#include <cctype>
#include <charconv>

#include <fmt/format.h>

namespace revolve::turntable::modbus {

// Recursive descent over the text; positions are reported 1-based.
class ExpressionParser {
 public:
  ExpressionParser(std::string_view text, StatusExpression& out) : text_(text), out_(out) {}

  Expected<int> ParseAll() {
    Expected<int> root = ParseOr();
    if (!root) return root;
    SkipSpace();
    if (pos_ != text_.size()) return Fail("unexpected text after the expression");
    return root;
  }

 private:
  using Node = StatusExpression::Node;
  using Kind = StatusExpression::Kind;
  using Op = StatusExpression::Op;

  std::unexpected<Error> Fail(std::string_view what) const {
    return MakeError(ErrorCode::kBadInput,
                     fmt::format("column {}: {} in \"{}\"", pos_ + 1, what, text_));
  }

  void SkipSpace() {
    while (pos_ < text_.size() && std::isspace(static_cast<unsigned char>(text_[pos_])) != 0) {
      ++pos_;
    }
  }

  bool Accept(std::string_view token) {
    SkipSpace();
    if (text_.substr(pos_, token.size()) == token) {
      pos_ += token.size();
      return true;
    }
    return false;
  }

  int Add(Node node) {
    out_.nodes_.push_back(std::move(node));
    return static_cast<int>(out_.nodes_.size()) - 1;
  }

  Expected<int> ParseOr() {
    Expected<int> left = ParseAnd();
    if (!left) return left;
    while (Accept("||")) {
      Expected<int> right = ParseAnd();
      if (!right) return right;
      Node node;
      node.kind = Kind::kOr;
      node.left = *left;
      node.right = *right;
      left = Add(std::move(node));
    }
    return left;
  }

  Expected<int> ParseAnd() {
    Expected<int> left = ParseUnary();
    if (!left) return left;
    while (Accept("&&")) {
      Expected<int> right = ParseUnary();
      if (!right) return right;
      Node node;
      node.kind = Kind::kAnd;
      node.left = *left;
      node.right = *right;
      left = Add(std::move(node));
    }
    return left;
  }

  Expected<int> ParseUnary() {
    SkipSpace();
    if (pos_ < text_.size() && text_[pos_] == '!' && text_.substr(pos_, 2) != "!=") {
      ++pos_;
      Expected<int> operand = ParseUnary();
      if (!operand) return operand;
      Node node;
      node.kind = Kind::kNot;
      node.left = *operand;
      return Add(std::move(node));
    }
    if (Accept("(")) {
      Expected<int> inner = ParseOr();
      if (!inner) return inner;
      if (!Accept(")")) return Fail("expected \")\"");
      return inner;
    }
    return ParseComparison();
  }

  std::string_view Identifier() {
    SkipSpace();
    const std::size_t start = pos_;
    while (pos_ < text_.size() && (std::isalnum(static_cast<unsigned char>(text_[pos_])) != 0 ||
                                   text_[pos_] == '_' || text_[pos_] == '.')) {
      ++pos_;
    }
    return text_.substr(start, pos_ - start);
  }

  Expected<std::int64_t> Number() {
    SkipSpace();
    bool negative = false;
    if (pos_ < text_.size() && text_[pos_] == '-') {
      negative = true;
      ++pos_;
    }
    int base = 10;
    if (text_.substr(pos_, 2) == "0x" || text_.substr(pos_, 2) == "0X") {
      base = 16;
      pos_ += 2;
    }
    std::int64_t value = 0;
    const char* begin = text_.data() + pos_;
    const char* end = text_.data() + text_.size();
    const auto [ptr, ec] = std::from_chars(begin, end, value, base);
    if (ec != std::errc() || ptr == begin) return Fail("expected a number");
    pos_ += static_cast<std::size_t>(ptr - begin);
    return negative ? -value : value;
  }

  Expected<int> ParseComparison() {
    const std::size_t start = pos_;
    std::string_view name = Identifier();
    if (name.empty() || std::isdigit(static_cast<unsigned char>(name[0])) != 0) {
      pos_ = start;
      SkipSpace();
      return Fail("expected a field name, \"!\", \"(\", true or false");
    }
    Node node;
    if (name == "true" || name == "false") {
      node.kind = Kind::kConstant;
      node.constant = name == "true";
      return Add(std::move(node));
    }
    node.field = std::string(name);
    node.kind = Kind::kTruthy;
    if (const std::size_t dot = name.find('.'); dot != std::string_view::npos) {
      const std::string_view suffix = name.substr(dot + 1);
      int bit = -1;
      if (suffix.starts_with("bit")) {
        const auto [ptr, ec] =
            std::from_chars(suffix.data() + 3, suffix.data() + suffix.size(), bit);
        if (ec != std::errc() || ptr != suffix.data() + suffix.size()) bit = -1;
      }
      if (bit < 0 || bit > 31) {
        return Fail(
            fmt::format("\"{}\": after a field name only .bit0 .. .bit31 may follow", name));
      }
      node.field = std::string(name.substr(0, dot));
      node.kind = Kind::kBit;
      node.bit = bit;
      return Add(std::move(node));
    }
    static constexpr std::pair<std::string_view, Op> kOps[] = {{"==", Op::kEq}, {"!=", Op::kNe},
                                                               {"<=", Op::kLe}, {">=", Op::kGe},
                                                               {"<", Op::kLt},  {">", Op::kGt}};
    for (const auto& [token, op] : kOps) {
      if (Accept(token)) {
        Expected<std::int64_t> number = Number();
        if (!number) return std::unexpected(number.error());
        node.kind = Kind::kCompare;
        node.op = op;
        node.numbers = {*number};
        return Add(std::move(node));
      }
    }
    const std::size_t before_in = pos_;
    if (Identifier() == "in") {
      if (!Accept("[")) return Fail("expected \"[\" after in");
      node.kind = Kind::kIn;
      do {
        Expected<std::int64_t> number = Number();
        if (!number) return std::unexpected(number.error());
        node.numbers.push_back(*number);
      } while (Accept(","));
      if (!Accept("]")) return Fail("expected \",\" or \"]\"");
      return Add(std::move(node));
    }
    pos_ = before_in;
    return Add(std::move(node));
  }

  std::string_view text_;
  StatusExpression& out_;
  std::size_t pos_ = 0;
};

StatusExpression::StatusExpression() : text_("false") { nodes_.push_back(Node{}); }

Expected<StatusExpression> StatusExpression::Parse(std::string_view text) {
  StatusExpression expression;
  expression.nodes_.clear();
  expression.text_ = std::string(text);
  ExpressionParser parser(text, expression);
  Expected<int> root = parser.ParseAll();
  if (!root) return std::unexpected(root.error());
  expression.root_ = *root;
  return expression;
}

bool StatusExpression::Evaluate(const FieldValues& values) const {
  return EvaluateNode(root_, values);
}

bool StatusExpression::EvaluateNode(int index, const FieldValues& values) const {
  const Node& node = nodes_[static_cast<std::size_t>(index)];
  auto value = [&values](const std::string& field) -> std::int64_t {
    const auto it = values.find(field);
    return it == values.end() ? 0 : it->second;
  };
  switch (node.kind) {
    case Kind::kConstant:
      return node.constant;
    case Kind::kTruthy:
      return value(node.field) != 0;
    case Kind::kBit:
      return ((static_cast<std::uint64_t>(value(node.field)) >> node.bit) & 1u) != 0;
    case Kind::kCompare: {
      const std::int64_t v = value(node.field);
      const std::int64_t n = node.numbers[0];
      switch (node.op) {
        case Op::kEq:
          return v == n;
        case Op::kNe:
          return v != n;
        case Op::kLt:
          return v < n;
        case Op::kLe:
          return v <= n;
        case Op::kGt:
          return v > n;
        case Op::kGe:
          return v >= n;
      }
      return false;
    }
    case Kind::kIn: {
      const std::int64_t v = value(node.field);
      for (std::int64_t n : node.numbers) {
        if (v == n) return true;
      }
      return false;
    }
    case Kind::kNot:
      return !EvaluateNode(node.left, values);
    case Kind::kAnd:
      return EvaluateNode(node.left, values) && EvaluateNode(node.right, values);
    case Kind::kOr:
      return EvaluateNode(node.left, values) || EvaluateNode(node.right, values);
  }
  return false;
}

std::set<std::string> StatusExpression::Fields() const {
  std::set<std::string> fields;
  for (const Node& node : nodes_) {
    if (!node.field.empty()) fields.insert(node.field);
  }
  return fields;
}

void StatusExpression::CollectCandidates(std::map<std::string, std::set<std::int64_t>>& values,
                                         std::map<std::string, std::set<int>>& bits) const {
  for (const Node& node : nodes_) {
    switch (node.kind) {
      case Kind::kTruthy:
        values[node.field].insert({0, 1});
        break;
      case Kind::kBit:
        bits[node.field].insert(node.bit);
        break;
      case Kind::kCompare:
        for (std::int64_t n : node.numbers) values[node.field].insert({n - 1, n, n + 1});
        break;
      case Kind::kIn:
        for (std::int64_t n : node.numbers) values[node.field].insert(n);
        break;
      default:
        break;
    }
  }
}

}  // namespace revolve::turntable::modbus
