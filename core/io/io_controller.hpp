// The I/O controller (the manual's 3.11, LinuxCNC's iocontrol): the E-stop
// chain, coolant, lube and the tool changer handshake over HAL pins
// (iocontrol.0.*), and the tool table it keeps and saves. It runs in the
// task cycle, never in the servo thread; a changer that does not answer in
// its timeout becomes an error instead of a hang.
#pragma once

#include <cstdint>
#include <filesystem>
#include <string>

#include "core/hal/component.hpp"
#include "core/ipc/service.hpp"
#include "core/tooltable/tool_table.hpp"

namespace cnc::io {

struct IoConfig {
  std::filesystem::path tool_table;           // [EMCIO]TOOL_TABLE (empty: none)
  tooltable::ChangerKind kind = tooltable::ChangerKind::NonRandom;  // [EMCIO]RANDOM_TOOLCHANGER
  double prepare_timeout_s = 30;              // [EMCIO]TOOL_PREPARE_TIMEOUT
  double change_timeout_s = 120;              // [EMCIO]TOOL_CHANGE_TIMEOUT
  double estop_reset_timeout_s = 1;           // [EMCIO]ESTOP_RESET_TIMEOUT: chain must close within
  static IoConfig from_ini(const ini::IniFile& ini);
};

enum class Handshake : uint8_t { Idle, Busy, Done, Failed };

class IoController : public hal::Component, public ipc::ControllerService {
 public:
  // Loads the tool table (throws ConfigError naming file and line).
  IoController(hal::Hal& hal, IoConfig config, MessageQueue* messages);

  // --- E-stop chain ---
  bool estop_chain_closed() const noexcept { return emc_enable_in_.get(); }
  // The chain's input pin, for motion to read in the servo thread.
  hal::BitPin estop_chain_pin() const noexcept { return emc_enable_in_; }
  // user-enable-out; a rising request also pulses user-request-enable.
  void set_user_enable(bool on, bool request_reset = false);
  bool user_enabled() const noexcept { return user_enable_out_.get(); }

  // --- coolant, lube ---
  void set_flood(bool on) { flood_.set(on); }
  void set_mist(bool on) { mist_.set(on); }
  void set_lube(bool on) { lube_.set(on); }

  // --- tool changer (one operation at a time) ---
  // T word: asks the changer to prepare a tool. Error text, or nullptr.
  const char* prepare(int tool_number);
  // M6: changes to the prepared tool (tooldata index from the interpreter).
  const char* change(int index);
  // M61: declares the tool at `index` to be in the spindle.
  const char* set_tool_number(int index);
  // G10 L1/L10/L11, or an edit from a client: updates and saves the table.
  const char* update_tool(const tooltable::Tool& tool);
  const char* delete_tool(int number);
  const char* reload_table();
  // State of the current operation; Done/Failed are reported once.
  Handshake poll();
  const std::string& failure() const noexcept { return failure_; }
  void abort();  // cancels a prepare or change in progress

  const tooltable::ToolTable& table() const noexcept { return table_; }
  int tool_in_spindle() const noexcept;
  int pocket_prepped() const noexcept { return pocket_prepped_; }
  int tool_prepped() const noexcept { return tool_prepped_; }

  // --- ControllerService ---
  int service_order() const noexcept override { return 20; }
  void update(int64_t now_ns) override;
  void contribute_status(ipc::Status& status) override;

 private:
  void fail(const std::string& why);
  void save_table();

  IoConfig config_;
  MessageQueue* messages_;
  tooltable::ToolTable table_;
  hal::BitPin emc_enable_in_, user_enable_out_, user_request_enable_;
  hal::BitPin flood_, mist_, lube_, lube_level_;
  hal::BitPin tool_prepare_, tool_prepared_, tool_change_, tool_changed_;
  hal::S32Pin tool_prep_number_, tool_prep_pocket_, tool_prep_index_, tool_number_, tool_from_pocket_;
  enum class Op : uint8_t { None, Prepare, Change } op_ = Op::None;
  Handshake state_ = Handshake::Idle;
  int64_t op_started_ns_ = 0;
  int64_t now_ns_ = 0;
  int64_t request_pulse_until_ns_ = 0;
  int pending_index_ = 0;
  int pocket_prepped_ = -1;
  int tool_prepped_ = 0;
  std::string failure_;
};

}  // namespace cnc::io
