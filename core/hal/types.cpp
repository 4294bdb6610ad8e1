#include "core/hal/types.hpp"

#include <cinttypes>
#include <cstdio>

#include "core/util/strings.hpp"

namespace cnc::hal {

const char* to_string(Type t) noexcept {
  switch (t) {
    case Type::Bit: return "bit";
    case Type::Float: return "float";
    case Type::S32: return "s32";
    case Type::U32: return "u32";
    case Type::S64: return "s64";
    case Type::U64: return "u64";
  }
  return "?";
}

const char* to_string(PinDir d) noexcept {
  switch (d) {
    case PinDir::In: return "IN";
    case PinDir::Out: return "OUT";
    case PinDir::IO: return "I/O";
  }
  return "?";
}

const char* to_string(ParamDir d) noexcept { return d == ParamDir::RO ? "RO" : "RW"; }

std::optional<Type> parse_type(std::string_view s) noexcept {
  for (Type t : {Type::Bit, Type::Float, Type::S32, Type::U32, Type::S64, Type::U64}) {
    if (iequals(s, to_string(t))) return t;
  }
  return std::nullopt;
}

std::string format_value(Type type, uint64_t bits) {
  char buf[48];
  switch (type) {
    case Type::Bit: return decode<bool>(bits) ? "TRUE" : "FALSE";
    case Type::Float: std::snprintf(buf, sizeof buf, "%.7g", decode<double>(bits)); return buf;
    case Type::S32: std::snprintf(buf, sizeof buf, "%" PRId32, decode<int32_t>(bits)); return buf;
    case Type::U32: std::snprintf(buf, sizeof buf, "%" PRIu32, decode<uint32_t>(bits)); return buf;
    case Type::S64: std::snprintf(buf, sizeof buf, "%" PRId64, decode<int64_t>(bits)); return buf;
    case Type::U64: std::snprintf(buf, sizeof buf, "%" PRIu64, decode<uint64_t>(bits)); return buf;
  }
  return "?";
}

std::optional<uint64_t> parse_value(Type type, std::string_view text) {
  text = trim(text);
  switch (type) {
    case Type::Bit: {
      const auto b = parse_bool(text);
      if (!b) return std::nullopt;
      return encode<bool>(*b);
    }
    case Type::Float: {
      const auto d = parse_double(text);
      if (!d) return std::nullopt;
      return encode<double>(*d);
    }
    case Type::S32: {
      const auto v = parse_int(text);
      if (!v || *v < INT32_MIN || *v > INT32_MAX) return std::nullopt;
      return encode<int32_t>(static_cast<int32_t>(*v));
    }
    case Type::U32: {
      const auto v = parse_uint(text);
      if (!v || *v > UINT32_MAX) return std::nullopt;
      return encode<uint32_t>(static_cast<uint32_t>(*v));
    }
    case Type::S64: {
      const auto v = parse_int(text);
      if (!v) return std::nullopt;
      return encode<int64_t>(*v);
    }
    case Type::U64: {
      const auto v = parse_uint(text);
      if (!v) return std::nullopt;
      return encode<uint64_t>(*v);
    }
  }
  return std::nullopt;
}

namespace {
// permissive: signal names (upper case and '_'); upper: pin names (upper case).
std::string check_common(std::string_view name, bool permissive, bool upper = false) {
  if (name.empty()) return "a name is needed";
  if (name.size() > kNameMax) {
    return "\"" + std::string(name) + "\" is " + std::to_string(name.size()) + " characters long, at most " +
           std::to_string(kNameMax) + " are allowed";
  }
  for (char c : name) {
    const bool ok = (c >= 'a' && c <= 'z') || (c >= '0' && c <= '9') || c == '.' || c == '-' ||
                    ((permissive || upper) && c >= 'A' && c <= 'Z') || (permissive && c == '_');
    if (!ok) {
      return "\"" + std::string(name) + "\" contains '" + std::string(1, c) +
             (permissive ? "': use letters, digits, '_', '-' and '.'"
              : upper    ? "': use letters and digits, '.' between levels and '-' between words"
                         : "': use lower-case letters and digits, '.' between levels and '-' between words");
    }
  }
  if (name.front() == '.' || name.back() == '.' || name.find("..") != std::string_view::npos) {
    return "\"" + std::string(name) + "\" has an empty level between dots";
  }
  return {};
}
}  // namespace

std::string check_name(std::string_view name) { return check_common(name, false); }
std::string check_signal_name(std::string_view name) { return check_common(name, true); }
std::string check_pin_name(std::string_view name) { return check_common(name, false, true); }

}  // namespace cnc::hal
