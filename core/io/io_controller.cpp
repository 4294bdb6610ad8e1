#include "core/io/io_controller.hpp"

#include "core/ini/ini_file.hpp"
#include "core/util/atomic_file.hpp"
#include "core/util/messages.hpp"
#include "core/util/time.hpp"

namespace cnc::io {

using hal::PinDir;

IoConfig IoConfig::from_ini(const ini::IniFile& ini) {
  IoConfig c;
  const std::string table = ini.get_string("EMCIO", "TOOL_TABLE", "");
  if (!table.empty()) c.tool_table = ini.resolve_path(table);
  c.kind = ini.get_bool("EMCIO", "RANDOM_TOOLCHANGER", false) ? tooltable::ChangerKind::Random
                                                              : tooltable::ChangerKind::NonRandom;
  c.prepare_timeout_s = ini.get_double("EMCIO", "TOOL_PREPARE_TIMEOUT", 30, {0.01, 3600});
  c.change_timeout_s = ini.get_double("EMCIO", "TOOL_CHANGE_TIMEOUT", 120, {0.01, 3600});
  c.estop_reset_timeout_s = ini.get_double("EMCIO", "ESTOP_RESET_TIMEOUT", 1, {0.001, 60});
  return c;
}

IoController::IoController(hal::Hal& hal, IoConfig config, MessageQueue* messages)
    : hal::Component(hal, "iocontrol"), config_(std::move(config)), messages_(messages), table_(config_.kind) {
  if (!config_.tool_table.empty()) {
    // Temporary files of a save that a kill interrupted.
    remove_stale_temporaries(config_.tool_table);
    if (std::filesystem::exists(config_.tool_table)) {
      table_ = tooltable::ToolTable::load(config_.tool_table, config_.kind);
    } else {
      throw ConfigError(config_.tool_table.string(), 0, "tool table file does not exist ([EMCIO]TOOL_TABLE)");
    }
  }
  const std::string n = "iocontrol.0.";
  emc_enable_in_ = make_pin<bool>(n + "emc-enable-in", PinDir::In);
  user_enable_out_ = make_pin<bool>(n + "user-enable-out", PinDir::Out);
  user_request_enable_ = make_pin<bool>(n + "user-request-enable", PinDir::Out);
  flood_ = make_pin<bool>(n + "coolant-flood", PinDir::Out);
  mist_ = make_pin<bool>(n + "coolant-mist", PinDir::Out);
  lube_ = make_pin<bool>(n + "lube", PinDir::Out);
  lube_level_ = make_pin<bool>(n + "lube-level", PinDir::In, true);  // LinuxCNC: lube_level (chapter 2 forbids _)
  tool_prepare_ = make_pin<bool>(n + "tool-prepare", PinDir::Out);
  tool_prepared_ = make_pin<bool>(n + "tool-prepared", PinDir::In);
  tool_change_ = make_pin<bool>(n + "tool-change", PinDir::Out);
  tool_changed_ = make_pin<bool>(n + "tool-changed", PinDir::In);
  tool_prep_number_ = make_pin<int32_t>(n + "tool-prep-number", PinDir::Out);
  tool_prep_pocket_ = make_pin<int32_t>(n + "tool-prep-pocket", PinDir::Out);
  tool_prep_index_ = make_pin<int32_t>(n + "tool-prep-index", PinDir::Out);
  tool_number_ = make_pin<int32_t>(n + "tool-number", PinDir::Out, table_.spindle().is_empty() ? 0 : table_.spindle().number);
  tool_from_pocket_ = make_pin<int32_t>(n + "tool-from-pocket", PinDir::Out);
}

int IoController::tool_in_spindle() const noexcept {
  const tooltable::Tool& t = table_.spindle();
  return t.is_empty() ? 0 : t.number;
}

void IoController::set_user_enable(bool on, bool request_reset) {
  user_enable_out_.set(on);
  if (on && request_reset) {
    user_request_enable_.set(true);
    request_pulse_until_ns_ = monotonic_ns() + 50'000'000;  // long enough for any servo period
  }
}

const char* IoController::prepare(int tool_number) {
  if (op_ != Op::None) return "the tool changer is busy";
  int index = 0, pocket = 0;
  if (tool_number == 0 && !table_.is_random()) {
    index = 0;  // T0: no tool
  } else {
    const auto found = table_.find_tool_anywhere(tool_number);
    if (!found) {
      failure_ = "tool " + std::to_string(tool_number) + " is not in the tool table";
      return failure_.c_str();
    }
    index = *found;
    pocket = table_.at(index).pocket;
  }
  tool_prep_number_.set(tool_number);
  tool_prep_pocket_.set(pocket);
  tool_prep_index_.set(index);
  tool_prepare_.set(true);
  op_ = Op::Prepare;
  state_ = Handshake::Busy;
  op_started_ns_ = monotonic_ns();
  pending_index_ = index;
  tool_prepped_ = tool_number;
  return nullptr;
}

const char* IoController::change(int index) {
  if (op_ != Op::None) return "the tool changer is busy";
  pending_index_ = index;
  tool_from_pocket_.set(table_.at(index).pocket);
  tool_change_.set(true);
  op_ = Op::Change;
  state_ = Handshake::Busy;
  op_started_ns_ = monotonic_ns();
  return nullptr;
}

const char* IoController::set_tool_number(int index) {
  if (op_ != Op::None) return "the tool changer is busy";
  table_.set_spindle_tool(index);
  tool_number_.set(tool_in_spindle());
  return nullptr;
}

const char* IoController::update_tool(const tooltable::Tool& tool) {
  try {
    table_.update_tool(tool);
    if (table_.spindle().number == tool.number) tool_number_.set(tool.number);
    save_table();
  } catch (const std::exception& e) {
    failure_ = e.what();
    return failure_.c_str();
  }
  return nullptr;
}

const char* IoController::delete_tool(int number) {
  const auto idx = table_.find_tool(number);
  if (!idx) {
    failure_ = "tool " + std::to_string(number) + " is not in the tool table";
    return failure_.c_str();
  }
  if (table_.spindle().number == number) return "the tool is in the spindle: change it out first";
  table_.set_slot(*idx, tooltable::Tool{});
  try {
    save_table();
  } catch (const std::exception& e) {
    failure_ = e.what();
    return failure_.c_str();
  }
  return nullptr;
}

const char* IoController::reload_table() {
  if (op_ != Op::None) return "the tool changer is busy";
  if (config_.tool_table.empty()) return "no tool table is configured ([EMCIO]TOOL_TABLE)";
  try {
    const int in_spindle = tool_in_spindle();
    tooltable::ToolTable t = tooltable::ToolTable::load(config_.tool_table, config_.kind);
    if (!t.is_random() && in_spindle > 0) {
      if (const auto idx = t.find_tool(in_spindle)) t.set_spindle_tool(*idx);
    }
    table_ = std::move(t);
  } catch (const std::exception& e) {
    failure_ = e.what();
    return failure_.c_str();
  }
  return nullptr;
}

void IoController::save_table() {
  if (config_.tool_table.empty()) return;
  table_.save(config_.tool_table);
}

void IoController::fail(const std::string& why) {
  failure_ = why;
  state_ = Handshake::Failed;
  tool_prepare_.set(false);
  tool_change_.set(false);
  op_ = Op::None;
  if (messages_) messages_->post(MessageKind::Error, "iocontrol", why);
}

void IoController::abort() {
  tool_prepare_.set(false);
  tool_change_.set(false);
  op_ = Op::None;
  state_ = Handshake::Idle;
}

Handshake IoController::poll() {
  const Handshake s = state_;
  if (s == Handshake::Done || s == Handshake::Failed) state_ = Handshake::Idle;
  return s;
}

void IoController::update(int64_t now_ns) {
  now_ns_ = now_ns;
  if (request_pulse_until_ns_ && now_ns > request_pulse_until_ns_) {
    user_request_enable_.set(false);
    request_pulse_until_ns_ = 0;
  }
  const double elapsed = static_cast<double>(now_ns - op_started_ns_) * 1e-9;
  if (op_ == Op::Prepare) {
    if (tool_prepared_.get()) {
      tool_prepare_.set(false);
      pocket_prepped_ = pending_index_;
      op_ = Op::None;
      state_ = Handshake::Done;
    } else if (elapsed > config_.prepare_timeout_s) {
      fail("the tool changer did not answer tool-prepare within " + std::to_string(config_.prepare_timeout_s) +
           " s (iocontrol.0.tool-prepared stayed false; [EMCIO]TOOL_PREPARE_TIMEOUT)");
    }
  } else if (op_ == Op::Change) {
    if (tool_changed_.get()) {
      tool_change_.set(false);
      try {
        table_.change_tool(pending_index_);
        tool_number_.set(tool_in_spindle());
        if (table_.is_random()) save_table();  // pockets moved
        pocket_prepped_ = -1;
        op_ = Op::None;
        state_ = Handshake::Done;
      } catch (const std::exception& e) {
        fail(std::string("tool change: ") + e.what());
      }
    } else if (elapsed > config_.change_timeout_s) {
      fail("the tool changer did not finish within " + std::to_string(config_.change_timeout_s) +
           " s (iocontrol.0.tool-changed stayed false; [EMCIO]TOOL_CHANGE_TIMEOUT)");
    }
  }
}

void IoController::contribute_status(ipc::Status& s) {
  s.io.tool_in_spindle = tool_in_spindle();
  s.io.tool_diameter = table_.spindle().is_empty() ? 0 : table_.spindle().diameter;
  s.io.pocket_prepped = pocket_prepped_;
  s.io.tool_prepped = tool_prepped_;
  s.io.tool_change_in_progress = op_ == Op::Change;
  s.io.flood = flood_.get();
  s.io.mist = mist_.get();
  s.io.lube = lube_.get();
  s.io.lube_level_ok = lube_level_.get();
  s.io.estop_chain_ok = emc_enable_in_.get();
}

}  // namespace cnc::io
