// Status rules of a drive profile: small boolean expressions over raw register fields.
//
// Grammar (whitespace is free):
//   expr       := and ( "||" and )*
//   and        := unary ( "&&" unary )*
//   unary      := "!" unary | "(" expr ")" | "true" | "false" | comparison
//   comparison := operand [ ( "==" | "!=" | "<" | "<=" | ">" | ">=" ) number
//                          | "in" "[" number ( "," number )* "]" ]
//   operand    := FIELD | FIELD ".bit" N        (N in 0..31)
//   number     := [-] decimal | [-] 0x hex
// A bare operand is true when the value is non-zero ("st.bit5" tests bit 5; "enabled" tests the
// whole field). Field values are the raw decoded integers (signed for i16/i32), before `scale`.
//
// Examples: "status in [2, 3, 4, 5, 6]", "st.bit5 && !st.bit2", "status == 0 || stall == 1".
#pragma once

#include <cstdint>
#include <map>
#include <set>
#include <string>
#include <string_view>
#include <vector>

#include "base/error.h"

namespace revolve::turntable::modbus {

using FieldValues = std::map<std::string, std::int64_t, std::less<>>;

class StatusExpression {
 public:
  // A constant-false expression ("false").
  StatusExpression();

  // Parses `text`. Errors: bad_input "column <n>: <what is wrong>" (the caller adds the file and
  // key).
  static Expected<StatusExpression> Parse(std::string_view text);

  // Evaluates with `values`; a field missing from `values` reads as 0.
  bool Evaluate(const FieldValues& values) const;

  // The fields the expression reads, sorted.
  std::set<std::string> Fields() const;

  // Adds, per field, values worth trying when looking for register contents that make the
  // expression true or false (the drive simulator solves the rules this way): the compared
  // constants and their neighbours, and 0/1 for bare fields. Bits go to `bits`.
  void CollectCandidates(std::map<std::string, std::set<std::int64_t>>& values,
                         std::map<std::string, std::set<int>>& bits) const;

  const std::string& text() const { return text_; }

 private:
  enum class Kind { kConstant, kTruthy, kBit, kCompare, kIn, kNot, kAnd, kOr };
  enum class Op { kEq, kNe, kLt, kLe, kGt, kGe };
  struct Node {
    Kind kind = Kind::kConstant;
    bool constant = false;
    std::string field;
    int bit = 0;
    Op op = Op::kEq;
    std::vector<std::int64_t> numbers;  // kCompare: one; kIn: the list
    int left = -1;                      // kNot: operand; kAnd/kOr: left
    int right = -1;                     // kAnd/kOr
  };
  friend class ExpressionParser;

  bool EvaluateNode(int index, const FieldValues& values) const;

  std::string text_;
  std::vector<Node> nodes_;
  int root_ = 0;
};

}  // namespace revolve::turntable::modbus
