// Lexing and parsing of one line into a Block, and expression evaluation
// with LinuxCNC's operators, precedence and messages.
#include <charconv>
#include <cmath>
#include <cstdint>
#include <cstring>

#include "core/interp/impl.hpp"
#include "core/util/strings.hpp"

namespace cnc::interp {

namespace {

// Modal group of each G code (x10), -1 when unknown.
int g_group(int code) {
  switch (code) {
    case 40: case 100: case 280: case 281: case 300: case 301: case 520: case 530:
    case 920: case 921: case 922: case 923:
      return kGNonModal;
    case 0: case 10: case 20: case 30: case 50: case 51: case 52: case 53: case 330: case 331:
    case 382: case 383: case 384: case 385: case 730: case 740: case 760: case 800: case 810: case 820: case 830:
    case 840: case 850: case 860: case 870: case 880: case 890:
    case 700: case 710: case 711: case 712: case 720: case 721: case 722:
      return kGMotion;
    case 170: case 171: case 180: case 181: case 190: case 191: return kGPlane;
    case 900: case 910: return kGDistance;
    case 901: case 911: return kGIjk;
    case 930: case 940: case 950: return kGFeedMode;
    case 200: case 210: return kGUnits;
    case 400: case 410: case 411: case 420: case 421: return kGCutter;
    case 430: case 431: case 432: case 490: return kGToolOffset;
    case 980: case 990: return kGRetract;
    case 540: case 550: case 560: case 570: case 580: case 590: case 591: case 592: case 593: return kGCoordSys;
    case 610: case 611: case 640: return kGControl;
    case 960: case 970: return kGSpindleMode;
    case 70: case 80: return kGLathe;
    default: return -1;
  }
}

int m_group(int code) {
  switch (code) {
    case 0: case 1: case 2: case 30: case 60: case 98: case 99: return kMStop;
    case 62: case 63: case 64: case 65: case 66: case 67: case 68: return kMIo;
    case 6: case 61: return kMToolChange;
    case 3: case 4: case 5: case 19: return kMSpindle;
    case 7: case 8: case 9: return kMCoolant;
    case 48: case 49: case 50: case 51: case 52: case 53: return kMOverride;
    case 70: case 71: case 72: case 73: return kMState;
    default: return (code >= 100 && code <= 199) ? kMUser : -1;
  }
}

}  // namespace

int builtin_g_group(int code) { return g_group(code); }
int builtin_m_group(int code) { return m_group(code); }

namespace {

bool is_digit(char c) { return c >= '0' && c <= '9'; }
bool is_lower(char c) { return c >= 'a' && c <= 'z'; }

struct OpInfo {
  int op;  // 0 none
  int prec;
  std::size_t len;
};
enum Op { kNone, kPow, kMul, kDiv, kMod, kAdd, kSub, kEq, kNe, kGt, kGe, kLt, kLe, kAnd, kOr, kXor };

bool starts(const std::string& s, std::size_t i, const char* word) {
  const std::size_t n = std::strlen(word);
  return s.compare(i, n, word) == 0;
}

}  // namespace

void Block::clear() {
  line = 0;
  n_number = -1;
  n_text.clear();
  has = 0;
  has_polar_r = has_polar_a = false;
  g.fill(-1);
  m.fill(-1);
  m_count = 0;
  dollar = -1;
  has_dollar = false;
  has_comment = false;
  comment.clear();
  has_py = false;
  py_code.clear();
  o_type = OType::None;
  o_name.clear();
  o_has_value = false;
  o_value = 0;
  call_args.clear();
  assigns.clear();
  motion = -1;
}

bool Block::any_axis(unsigned mask) const noexcept {
  static constexpr char letters[] = "xyzabcuvw";
  for (int i = 0; i < 9; ++i) {
    if (((mask >> i) & 1u) && has_word(letters[i])) return true;
  }
  return false;
}

void Interpreter::State::fail(const std::string& message) const {
  throw InterpError(message, current_file, current_line, line_text);
}

void Interpreter::State::normalize(std::string_view raw) {
  norm.clear();
  norm.reserve(raw.size());
  bool in_comment = false;
  for (std::size_t k = 0; k < raw.size(); ++k) {
    const char c = raw[k];
    if (in_comment) {
      if (c == '(') fail("Nested comment found");
      norm.push_back(c);
      if (c == ')') in_comment = false;
      continue;
    }
    if (c == '(') {
      in_comment = true;
      norm.push_back(c);
    } else if (c == ';') {
      // `;py,statement`: a script statement, kept as written
      const std::string_view rest = raw.substr(k + 1);
      if (rest.size() >= 3 && cnc::iequals(rest.substr(0, 3), "py,")) {
        block.has_py = true;
        block.py_code.assign(rest.substr(3));
      }
      break;
    } else if (c == ' ' || c == '\t') {
      continue;
    } else if (c >= 'A' && c <= 'Z') {
      norm.push_back(static_cast<char>(c + ('a' - 'A')));
    } else {
      norm.push_back(c);
    }
  }
  if (in_comment) fail("Unclosed comment found");
}

void Interpreter::State::parse_line(std::string_view raw) {
  block.clear();
  block.line = current_line;
  normalize(raw);
  std::size_t i = 0;
  if (i < norm.size() && norm[i] == '/') {
    if (config.block_delete) {
      norm.clear();
      return;
    }
    ++i;
  }
  if (i < norm.size() && norm[i] == 'n') {
    ++i;
    const std::size_t start = i;
    int n = 0;
    while (i < norm.size() && is_digit(norm[i])) {
      n = n * 10 + (norm[i] - '0');
      if (n > 99999999) fail("Bad format unsigned integer");
      ++i;
    }
    if (i == start) fail("Bad format unsigned integer");
    block.n_text.assign(norm, start, i - start);
    // LinuxCNC accepts and ignores a fractional N (N10.1).
    if (i < norm.size() && norm[i] == '.') {
      ++i;
      while (i < norm.size() && is_digit(norm[i])) ++i;
    }
    block.n_number = n;
  }
  if (i < norm.size() && norm[i] == 'o') {
    read_o_word(i);
    return;
  }
  parse_words(i);
}

void Interpreter::State::parse_words(std::size_t& i) {
  while (i < norm.size()) {
    const char c = norm[i];
    if (c == '(') {
      read_comment(i);
    } else if (c == '#') {
      read_parameter_setting(i);
    } else if (is_lower(c) || c == '$') {
      read_word(i);
    } else if (c == '@' || c == '^') {
      // polar coordinates: @ radius, ^ angle (degrees)
      ++i;
      const bool radius = c == '@';
      if (radius ? block.has_polar_r : block.has_polar_a) {
        fail(radius ? "Multiple @ words on one line" : "Multiple ^ words on one line");
      }
      const double v = read_real_value(i);
      if (radius) {
        block.has_polar_r = true;
        block.polar_r = v;
      } else {
        block.has_polar_a = true;
        block.polar_a = v;
      }
    } else {
      char buf[64];
      if (static_cast<unsigned char>(c) < 32 || static_cast<unsigned char>(c) > 126) {
        std::snprintf(buf, sizeof buf, "Bad character '\\%03o' used", static_cast<unsigned char>(c));
      } else {
        std::snprintf(buf, sizeof buf, "Bad character '%c' used", c);
      }
      fail(buf);
    }
  }
}

void Interpreter::State::read_comment(std::size_t& i) {
  const std::size_t close = norm.find(')', i);
  block.comment.assign(norm, i + 1, close - i - 1);
  block.has_comment = true;
  i = close + 1;
}

void Interpreter::State::add_g(int code) {
  int group = g_group(code);
  if (group < 0 && find_remap('g', code, true) != nullptr) group = kGMotion;
  if (group < 0) fail("Unknown g code used");
  if (block.g[static_cast<std::size_t>(group)] != -1) fail("Two g codes used from same modal group");
  block.g[static_cast<std::size_t>(group)] = code;
}

void Interpreter::State::add_m(int code) {
  int group = m_group(code);
  const RemapSpec* remap = find_remap('m', code, true);
  if (remap != nullptr) group = remap->modal_group;
  if (code > 199 && remap == nullptr) fail("M-code greater than 199: M" + std::to_string(code));
  if (group < 0) fail("Unknown m code used: M" + std::to_string(code));
  if (block.m[static_cast<std::size_t>(group)] != -1) fail("Two m codes used from same modal group");
  if (++block.m_count > 4) fail("Too many m codes on line");
  block.m[static_cast<std::size_t>(group)] = code;
}

void Interpreter::State::read_word(std::size_t& i) {
  const char letter = norm[i++];
  auto multiple = [&](char l) {
    char buf[48];
    const bool upper = l == 'u' || l == 'v' || l == 'w';
    std::snprintf(buf, sizeof buf, "Multiple %c words on one line", upper ? static_cast<char>(l - 32) : l);
    fail(buf);
  };
  switch (letter) {
    case 'g': {
      const double v = read_real_value(i) * 10.0;
      if (v > 1e7 || v < -1e7) fail(v < 0 ? "Negative g code used" : "Unknown g code used");
      const int code = static_cast<int>(std::floor(v + 0.5));
      if (v < code - 0.0001 || v > code + 0.0001) fail("Unknown g code used");
      if (code < 0) fail("Negative g code used");
      add_g(code);
      return;
    }
    case 'm': {
      const int code = read_integer_value(i);
      if (code < 0) fail("Negative m code used");
      add_m(code);
      return;
    }
    case '$': {
      if (block.has_dollar) fail("Multiple spindle choice ($) words on one line");
      block.dollar = read_integer_value(i);
      block.has_dollar = true;
      return;
    }
    case 'n':
    case 'o':
      fail(std::string("Bad character '") + letter + "' used");
    default:
      break;
  }
  const int axis = axis_index(letter);
  // A G7x contour reads A (fillet), C (chamfer), U and W (relative X, Z)
  // whatever the machine's axes, as LinuxCNC does.
  const bool contour_word = capture_depth >= 0 && (letter == 'a' || letter == 'c' || letter == 'u' || letter == 'w');
  if (axis >= 0 && !((config.axis_mask >> axis) & 1u) && !contour_word) {
    fail(std::string("Bad character '") + letter + "' used");
  }
  static constexpr uint32_t kWordLetters = 0x3ffffff & ~((1u << ('g' - 'a')) | (1u << ('m' - 'a')) | (1u << ('n' - 'a')) |
                                                          (1u << ('o' - 'a')));
  if (letter < 'a' || letter > 'z' || !((kWordLetters >> (letter - 'a')) & 1u)) {
    fail(std::string("Bad character '") + letter + "' used");
  }
  if (block.has_word(letter)) multiple(letter);
  double value = 0;
  switch (letter) {
    case 'h': {
      const int n = read_integer_value(i);
      if (n < 0) fail("Negative h word used");
      value = n;
      break;
    }
    case 'l': {
      const int n = read_integer_value(i);
      if (n < 0) fail("Negative l word used");
      value = n;
      break;
    }
    case 't': {
      const int n = read_integer_value(i);
      if (n < 0) fail("Negative tool id (tool not found)");
      value = n;
      break;
    }
    case 'f':
      value = read_real_value(i);
      if (value < 0) fail("Negative f word used");
      break;
    case 's':
      value = read_real_value(i);
      if (value < 0) fail("Negative spindle speed used");
      break;
    default:
      value = read_real_value(i);
      break;
  }
  block.set(letter, value);
}

double Interpreter::State::read_real_value(std::size_t& i) {
  if (i >= norm.size()) fail("No characters found in reading real value");
  const char c = norm[i];
  const char c1 = i + 1 < norm.size() ? norm[i + 1] : '\0';
  double v = 0;
  if (c == '[') {
    v = read_expression(i);
  } else if (c == '#') {
    v = read_parameter(i);
  } else if (c == '+' && c1 != '\0' && !is_digit(c1) && c1 != '.') {
    ++i;
    v = read_real_value(i);
  } else if (c == '-' && c1 != '\0' && !is_digit(c1) && c1 != '.') {
    ++i;
    v = -read_real_value(i);
  } else if (is_lower(c)) {
    v = read_unary(i);
  } else {
    v = read_real_number(i);
  }
  if (std::isnan(v)) fail("Calculation resulted in 'not a number'");
  if (std::isinf(v)) fail("Calculation resulted in 'infinity'");
  return v;
}

double Interpreter::State::read_real_number(std::size_t& i) {
  std::size_t j = i;
  bool negative = false;
  if (j < norm.size() && (norm[j] == '+' || norm[j] == '-')) {
    negative = norm[j] == '-';
    ++j;
  }
  const std::size_t start = j;
  bool point = false;
  int digits = 0;
  while (j < norm.size()) {
    const char c = norm[j];
    if (is_digit(c)) {
      ++digits;
    } else if (c == '.' && !point) {
      point = true;
    } else {
      break;
    }
    ++j;
  }
  if (digits == 0) {
    if (j == i && i >= norm.size()) fail("No characters found in reading real value");
    fail("bad number format (conversion failed) parsing '" + norm.substr(i, j - i) + "'");
  }
  double v = 0;
  const char* first = norm.data() + start;
  const char* last = norm.data() + j;
  // Fast path (exact, as strtod): up to 15 significant digits scaled by an
  // exact power of ten is one correctly rounded division.
  static constexpr double kPow10[] = {1e0,  1e1,  1e2,  1e3,  1e4,  1e5,  1e6,  1e7,  1e8,  1e9,  1e10, 1e11,
                                      1e12, 1e13, 1e14, 1e15, 1e16, 1e17, 1e18, 1e19, 1e20, 1e21, 1e22};
  if (digits <= 15) {
    uint64_t mantissa = 0;
    int frac = 0;
    bool after_point = false;
    for (const char* c = first; c < last; ++c) {
      if (*c == '.') {
        after_point = true;
        continue;
      }
      mantissa = mantissa * 10 + static_cast<uint64_t>(*c - '0');
      frac += after_point ? 1 : 0;
    }
    v = static_cast<double>(mantissa) / kPow10[frac];
  } else {
    const auto r = std::from_chars(first, last, v, std::chars_format::fixed);
    if (r.ec != std::errc() || r.ptr != last) {
      // "5." is valid G-code; from_chars stops before a trailing point.
      if (r.ec == std::errc() && r.ptr + 1 == last && *r.ptr == '.') {
        // ok
      } else if (r.ec == std::errc::result_out_of_range) {
        fail("Calculation resulted in 'infinity'");
      } else {
        fail("Bad number format");
      }
    }
  }
  i = j;
  return negative ? -v : v;
}

int Interpreter::State::read_integer_value(std::size_t& i) {
  const double v = read_real_value(i);
  const double n = std::floor(v + 0.5);
  if (std::fabs(v - n) > 0.0001) fail("Non integer value for integer");
  if (n > 2147483647.0 || n < -2147483647.0) fail("Non integer value for integer");
  return static_cast<int>(n);
}

std::string Interpreter::State::read_name(std::size_t& i) {
  // at '<'
  const std::size_t close = norm.find('>', i);
  if (close == std::string::npos) fail("Named parameter not terminated");
  std::string name = norm.substr(i + 1, close - i - 1);
  i = close + 1;
  return name;
}

double Interpreter::State::read_parameter(std::size_t& i, bool for_exists) {
  ++i;  // '#'
  if (i < norm.size() && norm[i] == '<') {
    const std::string name = read_name(i);
    double v = 0;
    const bool found = find_named(name, v);
    if (for_exists) return found ? 1.0 : 0.0;
    // Inside a subroutine definition being passed over (its O-word lines
    // are read), names need not be defined yet, as in LinuxCNC.
    if (!found && skip_defining) return 0.0;
    if (!found) fail("Named parameter #<" + name + "> not defined");
    return v;
  }
  const int index = read_integer_value(i);
  if (for_exists) return index >= 1 && index < kMaxParameters ? 1.0 : 0.0;
  if (index < 1 || index >= kMaxParameters) fail("Parameter number out of range");
  if (index >= 5420 && index <= 5428 && cutter_side != 400) {
    fail("Cannot read current position with cutter radius compensation on");
  }
  return get_param(index);
}

void Interpreter::State::read_parameter_setting(std::size_t& i) {
  Assignment a;
  ++i;  // '#'
  if (i < norm.size() && norm[i] == '<') {
    a.name = read_name(i);
  } else {
    a.index = read_integer_value(i);
    if (a.index < 1 || a.index >= kMaxParameters) fail("Parameter number out of range");
  }
  if (i >= norm.size() || norm[i] != '=') fail("Equal sign missing in parameter setting");
  ++i;
  a.value = read_real_value(i);
  block.assigns.push_back(std::move(a));
}

double Interpreter::State::read_unary(std::size_t& i) {
  struct Fn {
    const char* name;
    int id;
  };
  static constexpr Fn fns[] = {{"abs", 1},  {"acos", 2}, {"asin", 3},  {"atan", 4}, {"cos", 5},
                               {"exists", 6}, {"exp", 7}, {"fix", 8},  {"fup", 9},  {"ln", 10},
                               {"round", 11}, {"sin", 12}, {"sqrt", 13}, {"tan", 14}};
  int id = 0;
  std::size_t len = 0;
  for (const Fn& f : fns) {
    if (starts(norm, i, f.name)) {
      // prefer the longest match (exists vs exp)
      if (std::strlen(f.name) > len) {
        id = f.id;
        len = std::strlen(f.name);
      }
    }
  }
  if (id == 0) {
    const char c = norm[i];
    if (std::strchr("acefhlrst", c) && c != 'h') {
      fail(std::string("Unknown word starting with ") + c);
    }
    fail("Unknown word where unary operation could be");
  }
  i += len;
  if (i >= norm.size() || norm[i] != '[') fail("Left bracket missing after unary operation name");
  if (id == 6) {  // EXISTS[#<name>]
    ++i;
    if (i >= norm.size() || norm[i] != '#') fail("Expected # reading parameter");
    const double v = read_parameter(i, true);
    if (i >= norm.size() || norm[i] != ']') fail("Expected ] reading bracketed parameter");
    ++i;
    return v;
  }
  double x = read_expression(i);
  // In long double, as LinuxCNC (its M_PIl makes sin(180) -5e-20, not
  // +1.2e-16: the sign shows in "%.4f" output as -0.0000).
  constexpr long double kPiL = 3.141592653589793238462643383279502884L;
  auto rad = [](double d) { return static_cast<long double>(d) * kPiL / 180.0L; };
  auto deg = [](long double r) { return static_cast<double>(r * 180.0L / kPiL); };
  switch (id) {
    case 1: return std::fabs(x);
    case 2:
      if (x < -1.0 || x > 1.0) fail("Argument to acos out of range");
      return deg(std::acos(static_cast<long double>(x)));
    case 3:
      if (x < -1.0 || x > 1.0) fail("Argument to asin out of range");
      return deg(std::asin(static_cast<long double>(x)));
    case 4: {
      if (i >= norm.size() || norm[i] != '/') fail("Slash missing after first atan argument");
      ++i;
      if (i >= norm.size() || norm[i] != '[') fail("Left bracket missing after slash with atan");
      const double y = read_expression(i);
      return deg(std::atan2(static_cast<long double>(x), static_cast<long double>(y)));
    }
    case 5: return static_cast<double>(std::cos(rad(x)));
    case 7: return std::exp(x);
    case 8: return std::floor(x);
    case 9: return std::ceil(x);
    case 10:
      if (x <= 0.0) fail("Zero or negative argument to ln");
      return std::log(x);
    case 11: return static_cast<double>(static_cast<long long>(x + ((x < 0.0) ? -0.5 : 0.5)));
    case 12: return static_cast<double>(std::sin(rad(x)));
    case 13:
      if (x < 0.0) fail("Negative argument to sqrt");
      return std::sqrt(x);
    case 14: return static_cast<double>(std::tan(rad(x)));
    default: return x;
  }
}

namespace {
OpInfo read_op(const std::string& s, std::size_t i) {
  if (i >= s.size()) return {kNone, 0, 0};
  switch (s[i]) {
    case '*':
      if (i + 1 < s.size() && s[i + 1] == '*') return {kPow, 6, 2};
      return {kMul, 5, 1};
    case '/': return {kDiv, 5, 1};
    case '+': return {kAdd, 4, 1};
    case '-': return {kSub, 4, 1};
    default: break;
  }
  static constexpr struct {
    const char* w;
    int op;
    int prec;
  } words[] = {{"mod", kMod, 5}, {"eq", kEq, 3}, {"ne", kNe, 3}, {"gt", kGt, 3}, {"ge", kGe, 3}, {"lt", kLt, 3},
               {"le", kLe, 3},   {"and", kAnd, 2}, {"or", kOr, 2}, {"xor", kXor, 2}};
  for (const auto& w : words) {
    if (starts(s, i, w.w)) return {w.op, w.prec, std::strlen(w.w)};
  }
  return {-1, 0, 0};
}
}  // namespace

double Interpreter::State::read_expression(std::size_t& i) {
  // at '['; LinuxCNC's algorithm: values and operators on stacks, an
  // operator reduces while the previous one binds at least as tightly.
  ++i;
  double values[8];
  int ops[8];
  int precs[8];
  int nv = 0, no = 0;
  auto apply = [&](double left, int op, double right) -> double {
    switch (op) {
      case kPow:
        if (left < 0.0 && std::floor(right) != right) fail("Attempt to raise negative to non integer power");
        return std::pow(left, right);
      case kMul: return left * right;
      case kDiv:
        if (right == 0.0) fail("Attempt to divide by zero");
        return left / right;
      case kMod: {
        double r = std::fmod(left, right);
        if (r < 0.0) r += std::fabs(right);
        return r;
      }
      case kAdd: return left + right;
      case kSub: return left - right;
      case kEq: return std::fabs(left - right) < 0.000001 ? 1.0 : 0.0;
      case kNe: return std::fabs(left - right) >= 0.000001 ? 1.0 : 0.0;
      case kGt: return left > right ? 1.0 : 0.0;
      case kGe: return left >= right ? 1.0 : 0.0;
      case kLt: return left < right ? 1.0 : 0.0;
      case kLe: return left <= right ? 1.0 : 0.0;
      case kAnd: return (left == 0.0 || right == 0.0) ? 0.0 : 1.0;
      case kOr: return (left != 0.0 || right != 0.0) ? 1.0 : 0.0;
      case kXor: return ((left == 0.0) != (right == 0.0)) ? 1.0 : 0.0;
      default: return right;
    }
  };
  values[nv++] = read_real_value(i);
  for (;;) {
    if (i >= norm.size()) fail("Unclosed expression");
    if (norm[i] == ']') {
      ++i;
      while (no > 0) {
        const double r = values[--nv];
        values[nv - 1] = apply(values[nv - 1], ops[--no], r);
      }
      return values[0];
    }
    const OpInfo op = read_op(norm, i);
    if (op.op <= 0) {
      const char c = norm[i];
      if (std::strchr("egmnlox", c) && is_lower(c)) fail(std::string("Unknown operation name starting with ") + c);
      fail("Unknown operation");
    }
    i += op.len;
    while (no > 0 && precs[no - 1] >= op.prec) {
      const double r = values[--nv];
      values[nv - 1] = apply(values[nv - 1], ops[--no], r);
    }
    ops[no] = op.op;
    precs[no++] = op.prec;
    values[nv++] = read_real_value(i);
  }
}

void Interpreter::State::read_o_word(std::size_t& i) {
  ++i;  // 'o'
  std::string label;
  if (i < norm.size() && norm[i] == '<') {
    const std::size_t close = norm.find('>', i);
    if (close == std::string::npos) fail("Named parameter not terminated");
    label = norm.substr(i + 1, close - i - 1);
    i = close + 1;
  } else if (i < norm.size() && (norm[i] == '[' || norm[i] == '#')) {
    // o[expr] and o#n, o#<name>: the label is the integer value
    label = std::to_string(read_integer_value(i));
  } else {
    const std::size_t start = i;
    while (i < norm.size() && is_digit(norm[i])) ++i;
    if (i == start) fail("Unknown control command in o word");
    // As LinuxCNC reads it, an integer: o0100 and o100 are the same label.
    std::size_t first = start;
    while (first + 1 < i && norm[first] == '0') ++first;
    label = norm.substr(first, i - first);
  }
  block.o_name = label;
  struct Kw {
    const char* w;
    OType t;
  };
  static constexpr Kw kws[] = {{"endsub", OType::EndSub},     {"sub", OType::Sub},          {"call", OType::Call},
                               {"return", OType::Return},     {"elseif", OType::ElseIf},    {"else", OType::Else},
                               {"endif", OType::EndIf},       {"if", OType::If},            {"do", OType::Do},
                               {"endwhile", OType::EndWhile}, {"while", OType::While},      {"endrepeat", OType::EndRepeat},
                               {"repeat", OType::Repeat},     {"break", OType::Break},      {"continue", OType::Continue}};
  for (const Kw& k : kws) {
    if (starts(norm, i, k.w)) {
      block.o_type = k.t;
      i += std::strlen(k.w);
      break;
    }
  }
  if (block.o_type == OType::None) {
    // Nothing but comments after the label: a Fanuc-style subprogram start
    // or a program title (O1000, O<name>).
    std::size_t k = i;
    while (k < norm.size() && norm[k] == '(') {
      const std::size_t close = norm.find(')', k);
      if (close == std::string::npos) break;
      k = close + 1;
    }
    if (k < norm.size() && norm[k] != ';') fail("Unknown control command in o word");
    block.o_type = OType::FanucSub;
  }
  auto need_bracket = [&](const char* what) {
    if (i >= norm.size() || norm[i] != '[') fail(std::string("Left bracket missing after '") + what + "'");
  };
  switch (block.o_type) {
    case OType::If: need_bracket("if"); break;
    case OType::ElseIf: need_bracket("elseif"); break;
    case OType::While: need_bracket("while"); break;
    case OType::Repeat: need_bracket("repeat"); break;
    default: break;
  }
  // The condition and arguments are evaluated lazily by the flow code (a
  // skipped block must not evaluate them); remember where they start.
  block.o_has_value = false;
  o_args_pos = i;
}

}  // namespace cnc::interp
