#include "cia402/drive_group.hpp"

#include <cmath>
#include <cstdio>
#include <set>
#include <stdexcept>

#include "core/ini/ini_file.hpp"
#include "core/util/messages.hpp"
#include "core/util/strings.hpp"

namespace cnc::cia402 {
namespace {

constexpr uint32_t kAbortNoObject = 0x06020000;
constexpr int64_t kMs = 1'000'000;

std::string drive_source(const std::string& group, int number) {
  char buf[64];
  std::snprintf(buf, sizeof buf, "%s.drive.%02d", group.c_str(), number);
  return buf;
}

DriveConfig load_drive(const ini::IniFile& ini, const std::string& section, const std::string& group, int number) {
  DriveConfig d;
  d.origin = "[" + section + "]";
  d.source = drive_source(group, number);
  d.address = static_cast<int>(ini.require_int(section, "ADDRESS", {1, 65535}));
  d.name = ini.get_string(section, "NAME", "");
  if (d.name.empty()) d.name = d.source;
  d.joint = static_cast<int>(ini.get_int(section, "JOINT", -1, {-1, 15}));
  const std::string mode = ini.get_string(section, "MODE", "CSP");
  if (!parse_mode(mode.c_str(), d.mode) || !is_cyclic(d.mode)) {
    ini.fail(ini.find_entry(section, "MODE"), "\"" + mode + "\": expected CSP, CSV or CST");
  }
  const double counts = ini.require_double(section, "ENCODER_COUNTS", {1, 1e12});
  const double gear_motor = ini.get_double(section, "GEAR_MOTOR_REVS", 1, {1e-9, 1e9});
  const double gear_load = ini.get_double(section, "GEAR_LOAD_REVS", 1, {1e-9, 1e9});
  const double lead = ini.require_double(section, "SCREW_LEAD", {1e-9, 1e9});
  d.scaling = Scaling::from_mechanics(counts, gear_motor, gear_load, lead, ini.get_bool(section, "REVERSE", false));

  d.home_method = static_cast<int>(ini.get_int(section, "HOME_METHOD", 0, {-128, 37}));
  if (d.home_method != 0 && !is_defined_homing_method(d.home_method)) {
    ini.fail(ini.find_entry(section, "HOME_METHOD"), "method " + std::to_string(d.home_method) +
                                                          " is not defined by CiA 402 (1-14, 17-30, 33-35, 37, or negative)");
  }
  d.home_search_vel = ini.get_double(section, "HOME_SEARCH_VEL", 0, {0, 1e9});
  d.home_latch_vel = ini.get_double(section, "HOME_LATCH_VEL", 0, {0, 1e9});
  d.home_accel = ini.get_double(section, "HOME_ACCEL", 0, {0, 1e12});
  const double joint_offset =
      d.joint >= 0 ? ini.get_double("JOINT_" + std::to_string(d.joint), "HOME_OFFSET", 0) : 0.0;
  d.home_offset = ini.get_double(section, "HOME_OFFSET", joint_offset);

  d.ferror_window = ini.get_double(section, "FERROR_WINDOW", 0, {0, 1e9});
  d.ferror_timeout_ms = static_cast<uint16_t>(ini.get_int(section, "FERROR_TIMEOUT_MS", 0, {0, 65535}));
  d.quick_stop_decel = ini.get_double(section, "QUICK_STOP_DECEL", 0, {0, 1e12});
  d.profile_decel = ini.get_double(section, "PROFILE_DECEL", 0, {0, 1e12});
  d.max_torque_percent = ini.get_double(section, "MAX_TORQUE", 0, {0, 6553.5});
  d.quick_stop_option = static_cast<int16_t>(ini.get_int(section, "QUICK_STOP_OPTION", kQuickStopRamp, {0, 8}));
  d.fault_reaction_option = static_cast<int16_t>(ini.get_int(section, "FAULT_REACTION_OPTION", kQuickStopRamp, {0, 4}));
  d.abort_connection_option = static_cast<int16_t>(ini.get_int(section, "ABORT_CONNECTION_OPTION", kAbortFault, {0, 3}));
  d.enable_timeout_ns = ini.get_int(section, "ENABLE_TIMEOUT_MS", 1000, {10, 60'000}) * kMs;
  d.fault_reset_holdoff_ns = ini.get_int(section, "FAULT_RESET_HOLDOFF_MS", 1000, {0, 60'000}) * kMs;
  d.mode_timeout_ns = ini.get_int(section, "MODE_TIMEOUT_MS", 500, {10, 60'000}) * kMs;
  d.home_timeout_ns = ini.get_int(section, "HOME_TIMEOUT_S", 120, {1, 3600}) * 1'000'000'000;
  d.home_return_window = ini.get_double(section, "HOME_RETURN_WINDOW", 0.01, {0, 1e9});
  d.home_return_timeout_ns = ini.get_int(section, "HOME_RETURN_TIMEOUT_MS", 2000, {10, 600'000}) * kMs;
  d.standstill_velocity = ini.get_double(section, "STANDSTILL_VELOCITY", 0.01, {0, 1e9});
  d.probe = ini.get_bool(section, "PROBE", true);
  d.disabled = ini.get_bool(section, "DISABLED", false);
  return d;
}

}  // namespace

GroupConfig load_group_config(const ini::IniFile& ini, const std::string& section, const std::string& name) {
  GroupConfig g;
  g.name = name;
  g.section = section;
  if (!ini.has_section(section)) ini.fail(nullptr, "no [" + section + "] section (the drives of cia402)");
  g.bus = ini.get_string(section, "BUS", "canopen.0");
  g.watchdog_cycles = static_cast<int>(ini.get_int(section, "WATCHDOG_CYCLES", 3, {1, 1000}));
  const int stale_limit = static_cast<int>(ini.get_int(section, "STALE_LIMIT", 3, {0, 1000}));
  std::set<int> numbers, addresses;
  for (const ini::Entry* e : ini.find_all_entries(section, "DRIVE")) {
    for (const std::string& w : split_blanks(e->value)) {
      const auto v = parse_int(w);
      if (!v || *v < 0 || *v > 99) ini.fail(e, "\"" + w + "\": expected drive numbers 0..99");
      if (!numbers.insert(static_cast<int>(*v)).second) ini.fail(e, "drive " + w + " listed twice");
      const std::string ds = section + "_DRIVE_" + std::to_string(*v);
      if (!ini.has_section(ds)) ini.fail(e, "drive " + w + " has no [" + ds + "] section");
      DriveEntry d{static_cast<int>(*v), load_drive(ini, ds, name, static_cast<int>(*v))};
      d.config.stale_limit = stale_limit;
      if (!addresses.insert(d.config.address).second) {
        ini.fail(ini.find_entry(ds, "ADDRESS"), "address " + std::to_string(d.config.address) + " used by two drives");
      }
      g.drives.push_back(std::move(d));
    }
  }
  if (g.drives.empty()) ini.fail(nullptr, "[" + section + "] lists no DRIVE = <n>");
  return g;
}

DriveGroup::DriveGroup(GroupConfig config, DriveLink& link, MessageQueue* messages)
    : config_(std::move(config)), link_(link), messages_(messages) {
  for (const DriveEntry& e : config_.drives) {
    if (!link.has_device(e.config.address)) {
      throw std::runtime_error(e.config.origin + " " + e.config.source + ": address " +
                               std::to_string(e.config.address) + " is not a device of " + link.name());
    }
    drives_.push_back(std::make_unique<Drive>(e.config, link, messages));
    if (e.config.disabled) {
      // Loud: a joint that moves nothing must not go unnoticed.
      const std::string why = e.config.origin + " " + e.config.source + " (" + e.config.name + ", address " +
                              std::to_string(e.config.address) +
                              "): DISABLED for commissioning: the drive is never enabled, its joint follows its "
                              "command without moving anything";
      std::fprintf(stderr, "cncd warning [%s] %s\n", config_.name.c_str(), why.c_str());
      if (messages) messages->postf(MessageKind::Error, config_.name, "%s", why.c_str());
      continue;
    }
    drives_.back()->check_mapping();
  }
  commands_.resize(drives_.size());
  feedback_.resize(drives_.size());
}

void DriveGroup::configure() {
  for (auto& dp : drives_) {
    if (dp->config().disabled) continue;
    dp->update_period();
    const DriveConfig& d = dp->config();
    const Scaling& s = d.scaling;
    auto fail = [&](Object o, const std::string& why) {
      char obj[16];
      std::snprintf(obj, sizeof obj, "0x%04X:%02X", o.index, o.sub);
      throw std::runtime_error(config_.name + ": " + d.source + " (" + d.name + ", address " +
                               std::to_string(d.address) + "): " + obj + ": " + why);
    };
    ConfigResult r = link_.read_wait(d.address, obj::kDeviceType, 4);
    if (!r.ok) fail(obj::kDeviceType, r.text);
    if ((r.value & 0xFFFF) != 0x0192) {
      char why[96];
      std::snprintf(why, sizeof why, "device type 0x%08llX is not a CiA 402 drive (profile 0x0192)",
                    static_cast<unsigned long long>(r.value));
      fail(obj::kDeviceType, why);
    }
    r = link_.read_wait(d.address, obj::kSupportedModes, 4);
    if (!r.ok) fail(obj::kSupportedModes, r.text);
    auto need_mode = [&](Mode m) {
      if (!((r.value >> supported_mode_bit(m)) & 1u)) {
        fail(obj::kSupportedModes, std::string("the drive does not support mode ") + to_string(m));
      }
    };
    need_mode(d.mode);
    if (d.home_method != 0) need_mode(Mode::Homing);

    auto put = [&](Object o, uint64_t value, unsigned size, bool optional = false) {
      const ConfigResult w = link_.write_wait(d.address, o, value, size);
      if (!w.ok && !(optional && w.abort_code == kAbortNoObject)) fail(o, w.text);
    };
    // Interpolation period = the bus cycle (value x 10^index s).
    const int64_t cycle = link_.cycle_ns();
    if (cycle % kMs == 0 && cycle / kMs <= 255) {
      put(obj::kInterpolationPeriodValue, static_cast<uint64_t>(cycle / kMs), 1, true);
      put(obj::kInterpolationPeriodIndex, static_cast<uint8_t>(-3), 1, true);
    } else if (cycle % 1000 == 0 && cycle / 1000 <= 255) {
      put(obj::kInterpolationPeriodValue, static_cast<uint64_t>(cycle / 1000), 1, true);
      put(obj::kInterpolationPeriodIndex, static_cast<uint8_t>(-6), 1, true);
    }
    put(obj::kQuickStopOption, static_cast<uint16_t>(d.quick_stop_option), 2);
    put(obj::kFaultReactionOption, static_cast<uint16_t>(d.fault_reaction_option), 2, true);
    put(obj::kAbortConnection, static_cast<uint16_t>(d.abort_connection_option), 2, true);
    if (d.ferror_window > 0) put(obj::kFollowingErrorWindow, s.to_counts_magnitude(d.ferror_window), 4);
    if (d.ferror_timeout_ms > 0) put(obj::kFollowingErrorTimeout, d.ferror_timeout_ms, 2);
    if (d.quick_stop_decel > 0) put(obj::kQuickStopDeceleration, s.to_counts_magnitude(d.quick_stop_decel), 4);
    if (d.profile_decel > 0) put(obj::kProfileDeceleration, s.to_counts_magnitude(d.profile_decel), 4);
    if (d.max_torque_percent > 0) put(obj::kMaxTorque, static_cast<uint16_t>(std::lround(d.max_torque_percent * 10)), 2);
    if (d.home_method != 0) {
      put(obj::kHomingMethod, static_cast<uint8_t>(static_cast<int8_t>(d.home_method)), 1);
      if (d.home_search_vel > 0) put(obj::kHomingSpeedSwitch, s.to_counts_magnitude(d.home_search_vel), 4);
      if (d.home_latch_vel > 0) put(obj::kHomingSpeedZero, s.to_counts_magnitude(d.home_latch_vel), 4);
      if (d.home_accel > 0) put(obj::kHomingAcceleration, s.to_counts_magnitude(d.home_accel), 4);
      // After homing the drive's position reads HOME_OFFSET at its reference.
      const int64_t offset = s.to_counts(d.home_offset);
      put(obj::kHomeOffset, static_cast<uint32_t>(static_cast<int32_t>(offset)), 4);
    }
  }
}

void DriveGroup::read(int64_t now_ns) noexcept {
  for (std::size_t i = 0; i < drives_.size(); ++i) {
    if (drives_[i]->config().disabled) {
      // Loopback: the joint follows its command, nothing moves.
      DriveFeedback& f = feedback_[i];
      f.pos_fb = commands_[i].pos_cmd;
      f.vel_fb = 0;
      f.ferror = 0;
      f.state = State::SwitchOnDisabled;
      f.index_found = false;
      continue;
    }
    drives_[i]->read(now_ns, commands_[i], feedback_[i]);
  }
}

void DriveGroup::write(int64_t now_ns) noexcept {
  if (watchdog_enabled_) {
    if (watchdog_level_ != watchdog_last_) {
      watchdog_still_ = 0;
      if (watchdog_tripped_) {
        bool any_enable = false;
        for (const DriveCommand& c : commands_) any_enable = any_enable || c.enable;
        if (!any_enable) watchdog_tripped_ = false;  // motion runs again and the machine is off
      }
    } else if (++watchdog_still_ >= config_.watchdog_cycles && !watchdog_tripped_) {
      watchdog_tripped_ = true;
      if (messages_) {
        messages_->postf(MessageKind::Error, config_.name,
                         "motion watchdog stopped for %d cycles: drives stopped, %s outputs off", watchdog_still_,
                         link_.name().c_str());
      }
    }
  } else {
    watchdog_still_ = 0;
    watchdog_tripped_ = false;
  }
  watchdog_last_ = watchdog_level_;
  const bool shutdown = shutdown_.load(std::memory_order_relaxed);
  for (std::size_t i = 0; i < drives_.size(); ++i) {
    commands_[i].inhibit = watchdog_tripped_;
    if (shutdown) commands_[i].enable = false;  // an orderly disable: quick stop, then power off
    if (drives_[i]->config().disabled) {
      feedback_[i].enabled = commands_[i].enable && !commands_[i].inhibit;
      continue;
    }
    drives_[i]->write(now_ns, commands_[i], feedback_[i]);
  }
}

bool DriveGroup::is_safe() const noexcept {
  for (const auto& d : drives_) {
    if (!d->config().disabled && !d->is_safe()) return false;
  }
  return true;
}

}  // namespace cnc::cia402
