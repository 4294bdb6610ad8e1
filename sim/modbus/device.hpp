// What a simulated device answers per register: the drive families' maps
// (as their manuals describe them, written independently of the product's
// profiles) and a remote I/O module. Not product code (sim/ only).
#pragma once

#include <array>
#include <cstdint>
#include <string>

#include "sim/modbus/vfd_model.hpp"

namespace cnc::modbus_sim {

enum class Family { Gs2, Delta, Yaskawa, Atv, Huanyang, Io };

// "gs2", "delta", "yaskawa", "atv", "huanyang", "io"; false if unknown.
bool parse_family(const std::string& name, Family& out);
const char* to_string(Family f);
// The code each family reports for an over-current trip.
uint16_t overcurrent_code(Family f);

class Device {
 public:
  explicit Device(Family family, MotorParams motor = {});

  Family family() const noexcept { return family_; }
  VfdModel& model() noexcept { return model_; }

  // Holding (fc 3) and input (fc 4) registers; false: no such address.
  bool read_holding(uint16_t address, uint16_t& out) const;
  bool read_input(uint16_t address, uint16_t& out) const;
  bool write_holding(uint16_t address, uint16_t value);
  // Coils and discrete inputs (I/O module only).
  bool read_coil(uint16_t address, uint8_t& out) const;
  bool read_discrete(uint16_t address, uint8_t& out) const;
  bool write_coil(uint16_t address, uint8_t value);

  // The I/O module's process image, set by tests and the command line.
  static constexpr std::size_t kIoSize = 64;
  std::array<uint8_t, kIoSize> coils{}, discrete{};
  std::array<uint16_t, kIoSize> input_regs{}, holding_regs{};

 private:
  bool read_vfd(uint16_t address, uint16_t& out) const;
  Family family_;
  VfdModel model_;
  uint16_t gs2_direction_ = 0;
  uint16_t gs2_run_ = 0;
  uint16_t last_cmd_ = 0;
};

}  // namespace cnc::modbus_sim
