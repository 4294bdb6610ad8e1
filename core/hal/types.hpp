// HAL value types, directions, names and the 8-byte cell every pin,
// parameter and signal stores its value in. Cells are atomics: the servo
// thread writes them, halcmd reads them, nobody takes a lock.
#pragma once

#include <atomic>
#include <bit>
#include <cstdint>
#include <optional>
#include <stdexcept>
#include <string>
#include <string_view>
#include <type_traits>

namespace cnc::hal {

enum class Type : uint8_t { Bit, Float, S32, U32, S64, U64 };
enum class PinDir : uint8_t { In, Out, IO };
enum class ParamDir : uint8_t { RO, RW };

// HAL_NAME_LEN of the manual's chapter 2.
inline constexpr std::size_t kNameMax = 41;

const char* to_string(Type t) noexcept;      // "bit", "float", "s32", ...
const char* to_string(PinDir d) noexcept;    // "IN", "OUT", "I/O"
const char* to_string(ParamDir d) noexcept;  // "RO", "RW"
std::optional<Type> parse_type(std::string_view s) noexcept;

template <class T>
constexpr Type type_of() {
  if constexpr (std::is_same_v<T, bool>) return Type::Bit;
  else if constexpr (std::is_same_v<T, double>) return Type::Float;
  else if constexpr (std::is_same_v<T, int32_t>) return Type::S32;
  else if constexpr (std::is_same_v<T, uint32_t>) return Type::U32;
  else if constexpr (std::is_same_v<T, int64_t>) return Type::S64;
  else if constexpr (std::is_same_v<T, uint64_t>) return Type::U64;
  else static_assert(!sizeof(T), "HAL types: bool, double, int32_t, uint32_t, int64_t, uint64_t");
}

template <class T>
constexpr uint64_t encode(T v) noexcept {
  if constexpr (std::is_same_v<T, bool>) return v ? 1 : 0;
  else if constexpr (std::is_same_v<T, double>) return std::bit_cast<uint64_t>(v);
  else if constexpr (std::is_signed_v<T>) return static_cast<uint64_t>(static_cast<int64_t>(v));
  else return static_cast<uint64_t>(v);
}

template <class T>
constexpr T decode(uint64_t bits) noexcept {
  if constexpr (std::is_same_v<T, bool>) return bits != 0;
  else if constexpr (std::is_same_v<T, double>) return std::bit_cast<double>(bits);
  else return static_cast<T>(bits);
}

struct Cell {
  std::atomic<uint64_t> bits{0};

  template <class T>
  T get() const noexcept { return decode<T>(bits.load(std::memory_order_relaxed)); }
  template <class T>
  void set(T v) noexcept { bits.store(encode<T>(v), std::memory_order_relaxed); }
  uint64_t raw() const noexcept { return bits.load(std::memory_order_relaxed); }
  void set_raw(uint64_t v) noexcept { bits.store(v, std::memory_order_relaxed); }
};

// The value of a cell as halcmd prints it ("TRUE", "1.5", "-3", "0x...").
std::string format_value(Type type, uint64_t bits);
// Parses what halcmd accepts for a type; nullopt when it does not fit.
std::optional<uint64_t> parse_value(Type type, std::string_view text);

// Empty when `name` is a valid pin, parameter, function or thread name
// (chapter 2: lower case letters and digits, dots between levels, dashes
// between words, at most 41 characters); otherwise why not.
std::string check_name(std::string_view name);
// Pin and parameter names of components may also use upper-case letters:
// LinuxCNC's own components do (pid.0.Pgain, pid.0.FF0, encoder.0.phase-A)
// and panel HAL files name them so.
std::string check_pin_name(std::string_view name);
// Signal names are chosen by users in their HAL files: LinuxCNC configs use
// upper case and underscores there, so those are accepted too.
std::string check_signal_name(std::string_view name);

class HalError : public std::runtime_error {
 public:
  using std::runtime_error::runtime_error;
};

}  // namespace cnc::hal
