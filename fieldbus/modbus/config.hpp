// A Modbus link's configuration from the INI: [MODBUS] (or [MODBUS_n]) for
// the link, [MODBUS_VFD_s] / [MODBUS_n_VFD_s] per drive and
// [MODBUS_IO_s] / [MODBUS_n_IO_s] per remote I/O module, s the slave
// address (docs/modbus.md). Errors name the file, line and key.
#pragma once

#include <cstdint>
#include <string>
#include <vector>

#include "fieldbus/modbus/profile.hpp"

namespace cnc::ini {
class IniFile;
}

namespace cnc::modbus {

inline constexpr std::size_t kMaxIoValues = 128;  // pins per I/O module
inline constexpr std::size_t kMaxIoMaps = 16;     // map lines (polling groups) per I/O module

enum class Transport : uint8_t { Rtu, Tcp };

// What a VFD does when it has not answered for STALE_MS while running.
enum class CommLossAction : uint8_t { Fault, Warn };

struct VfdConfig {
  uint8_t slave = 1;
  std::string section;
  std::string name;           // NAME, for messages and the drive panel
  VfdProfile profile;
  double rpm_per_hz = 60;     // spindle rpm per Hz of output frequency
  double at_speed_tolerance = 0.02;  // fraction of the command
  int64_t poll_ns = 20'000'000;
  int64_t stale_ns = 500'000'000;
  CommLossAction on_comm_loss = CommLossAction::Fault;
};

enum class IoKind : uint8_t { Coil, DiscreteInput, InputRegister, HoldingRegister };
enum class IoType : uint8_t { Bit, Float, S32 };

// One map line: `count` consecutive items from `start`, polled together
// every `poll_ns` (a polling group).
struct IoMap {
  IoKind kind = IoKind::Coil;
  uint16_t start = 0;
  uint16_t count = 1;
  IoType type = IoType::Bit;
  double scale = 1;
  double offset = 0;
  bool is_signed = false;
  int64_t poll_ns = 50'000'000;
  std::size_t first_value = 0;  // index of its first value in the module's value array
  bool is_output() const noexcept { return kind == IoKind::Coil || kind == IoKind::HoldingRegister; }
};

struct IoConfig {
  uint8_t slave = 1;
  std::string section;
  std::string name;
  std::vector<IoMap> maps;
  std::size_t values = 0;
  int64_t stale_ns = 500'000'000;
};

struct LinkConfig {
  std::string section;  // MODBUS, MODBUS_1
  std::string name;     // HAL prefix: modbus.0
  Transport transport = Transport::Rtu;
  std::string device;   // RTU
  int baud = 19200;
  char parity = 'N';
  int data_bits = 8;
  int stop_bits = 1;
  std::string host;     // TCP
  int port = 502;
  int64_t timeout_ns = 100'000'000;
  int64_t retry_min_ns = 100'000'000;
  int64_t retry_max_ns = 2'000'000'000;
  std::vector<VfdConfig> vfds;
  std::vector<IoConfig> ios;

  // "tcp 127.0.0.1:502" or "rtu /dev/ttyUSB0 19200 8N1"
  std::string describe() const;
};

const char* to_string(IoKind k) noexcept;

LinkConfig load_link_config(const ini::IniFile& ini, const std::string& section, const std::string& name);

}  // namespace cnc::modbus
