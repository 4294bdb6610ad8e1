// Expressions: LinuxCNC's precedence (** > * / MOD > + - > relational >
// AND OR XOR, all left-associative) checked against a reference evaluator
// on seeded random expressions, and the functions' edge cases.
#include <gtest/gtest.h>

#include <cmath>
#include <random>

#include "core/interp/interp.hpp"
#include "core/interp/recording_canon.hpp"

using cnc::interp::InterpError;
using cnc::interp::Interpreter;
using cnc::interp::RecordingCanon;

namespace {

struct Evaluator {
  RecordingCanon canon;
  Interpreter in{canon};
  Evaluator() { in.init(); }
  double eval(const std::string& expr) {
    in.execute("#1 = " + expr);
    return in.parameter(1);
  }
  std::string error(const std::string& line) {
    try {
      in.execute(line);
    } catch (const InterpError& e) {
      return e.message();
    }
    return "(no error)";
  }
};

int prec(const std::string& op) {
  if (op == "**") return 6;
  if (op == "*" || op == "/" || op == "MOD") return 5;
  if (op == "+" || op == "-") return 4;
  if (op == "LT" || op == "GT" || op == "EQ") return 3;
  return 2;
}

double apply(double a, const std::string& op, double b) {
  if (op == "**") return std::pow(a, b);
  if (op == "*") return a * b;
  if (op == "/") return a / b;
  if (op == "MOD") {
    double r = std::fmod(a, b);
    return r < 0 ? r + std::fabs(b) : r;
  }
  if (op == "+") return a + b;
  if (op == "-") return a - b;
  if (op == "LT") return a < b;
  if (op == "GT") return a > b;
  if (op == "EQ") return std::fabs(a - b) < 1e-6;
  if (op == "AND") return a != 0 && b != 0;
  if (op == "OR") return a != 0 || b != 0;
  return (a != 0) != (b != 0);
}

// Shunting-yard with left associativity everywhere.
double reference(const std::vector<double>& v, const std::vector<std::string>& ops) {
  std::vector<double> vals{v[0]};
  std::vector<std::string> st;
  for (std::size_t i = 0; i < ops.size(); ++i) {
    while (!st.empty() && prec(st.back()) >= prec(ops[i])) {
      const double r = vals.back();
      vals.pop_back();
      vals.back() = apply(vals.back(), st.back(), r);
      st.pop_back();
    }
    st.push_back(ops[i]);
    vals.push_back(v[i + 1]);
  }
  while (!st.empty()) {
    const double r = vals.back();
    vals.pop_back();
    vals.back() = apply(vals.back(), st.back(), r);
    st.pop_back();
  }
  return vals[0];
}

}  // namespace

TEST(InterpExpression, RandomExpressionsFollowLinuxCncPrecedence) {
  const unsigned seed = std::random_device{}();
  SCOPED_TRACE("seed " + std::to_string(seed));
  std::mt19937 rng(seed);
  static const std::vector<std::string> all_ops = {"**", "*", "/", "MOD", "+", "-", "LT", "GT", "EQ", "AND", "OR", "XOR"};
  std::uniform_int_distribution<int> nops(1, 6), pick(0, static_cast<int>(all_ops.size()) - 1), num(1, 9);
  Evaluator e;
  for (int round = 0; round < 2000; ++round) {
    std::vector<double> v;
    std::vector<std::string> ops;
    const int n = nops(rng);
    v.push_back(num(rng));
    std::string text = "[" + std::to_string(static_cast<int>(v[0]));
    for (int k = 0; k < n; ++k) {
      ops.push_back(all_ops[static_cast<std::size_t>(pick(rng))]);
      v.push_back(num(rng));
      text += " " + ops.back() + " " + std::to_string(static_cast<int>(v.back()));
    }
    text += "]";
    const double want = reference(v, ops);
    if (!std::isfinite(want) || std::fabs(want) > 1e12) continue;
    const double got = e.eval(text);
    ASSERT_NEAR(got, want, 1e-9 * std::max(1.0, std::fabs(want))) << text;
  }
}

TEST(InterpExpression, FunctionsUseDegreesAndLinuxCncRounding) {
  Evaluator e;
  EXPECT_NEAR(e.eval("SIN[30]"), 0.5, 1e-12);
  EXPECT_NEAR(e.eval("COS[60]"), 0.5, 1e-12);
  EXPECT_NEAR(e.eval("TAN[45]"), 1.0, 1e-12);
  EXPECT_NEAR(e.eval("ASIN[1]"), 90.0, 1e-12);
  EXPECT_NEAR(e.eval("ACOS[0]"), 90.0, 1e-12);
  EXPECT_NEAR(e.eval("ATAN[1]/[-1]"), 135.0, 1e-12);
  EXPECT_EQ(e.eval("FIX[-1.5]"), -2.0);
  EXPECT_EQ(e.eval("FUP[-1.5]"), -1.0);
  EXPECT_EQ(e.eval("ROUND[-1.5]"), -2.0);
  EXPECT_EQ(e.eval("ROUND[1.49]"), 1.0);
  EXPECT_EQ(e.eval("ABS[-3]"), 3.0);
  EXPECT_NEAR(e.eval("EXP[LN[5]]"), 5.0, 1e-12);
  EXPECT_EQ(e.eval("SQRT[16]"), 4.0);
  EXPECT_EQ(e.eval("-[2]"), -2.0);
  EXPECT_EQ(e.eval("[-2 ** 2]"), 4.0) << "unary minus binds to the number";
  EXPECT_EQ(e.eval("[2 ** 3 ** 2]"), 64.0) << "left-associative power";
  EXPECT_EQ(e.eval("[-7 MOD 3]"), 2.0);
  EXPECT_EQ(e.eval("EXISTS[#<nothing>]"), 0.0);
}

TEST(InterpExpression, ErrorsUseLinuxCncWording) {
  Evaluator e;
  EXPECT_EQ(e.error("#1 = [1 / 0]"), "Attempt to divide by zero");
  EXPECT_EQ(e.error("#1 = SQRT[-1]"), "Negative argument to sqrt");
  EXPECT_EQ(e.error("#1 = LN[-1]"), "Zero or negative argument to ln");
  EXPECT_EQ(e.error("#1 = ACOS[1.5]"), "Argument to acos out of range");
  EXPECT_EQ(e.error("#1 = ASIN[-1.5]"), "Argument to asin out of range");
  EXPECT_EQ(e.error("#1 = [-8 ** 0.5]"), "Attempt to raise negative to non integer power");
  EXPECT_EQ(e.error("#1 = [1 + 2"), "Unclosed expression");
  EXPECT_EQ(e.error("#1 = [1 ? 2]"), "Unknown operation");
  EXPECT_EQ(e.error("#1 = [1 mud 2]"), "Unknown operation name starting with m");
  EXPECT_EQ(e.error("#1 = ATAN[1]"), "Slash missing after first atan argument");
  EXPECT_EQ(e.error("#1 = ATAN[1]/2"), "Left bracket missing after slash with atan");
  EXPECT_EQ(e.error("#1 = SIN 30"), "Left bracket missing after unary operation name");
  EXPECT_EQ(e.error("#1 = BOGUS[1]"), "Unknown word where unary operation could be");
  EXPECT_EQ(e.error("#1 = COZ[1]"), "Unknown word starting with c");
  EXPECT_EQ(e.error("#1 = #0"), "Parameter number out of range");
  EXPECT_EQ(e.error("#1 = #<undefined>"), "Named parameter #<undefined> not defined");
  EXPECT_EQ(e.error("#<_x> = 1"), "Cannot assign to read-only parameter #<_x>");
  EXPECT_EQ(e.error("#5401 = 1"), "Parameter is readonly");
  EXPECT_EQ(e.error("#1 = [EXP[1000]]"), "Calculation resulted in 'infinity'");
  EXPECT_EQ(e.error("G0 X"), "No characters found in reading real value");
}
