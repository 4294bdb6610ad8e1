#include "commission/controller.hpp"

#include <array>
#include <atomic>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <nlohmann/json.hpp>
#include <stdexcept>
#include <csignal>
#include <fstream>
#include <spawn.h>
#include <sstream>
#include <sys/wait.h>
#include <thread>

#include "commission/steps.hpp"
#include "core/ipc/client.hpp"

extern char** environ;

namespace cnc::commission {

namespace {
std::atomic<bool> g_abort{false};
std::string quote(const std::string& s) {
  std::string q = "'";
  for (char ch : s) q += ch == '\'' ? std::string("'\\''") : std::string(1, ch);
  return q + "'";
}
}  // namespace

std::string Controller::run(const std::filesystem::path& program, const std::vector<std::string>& args) const {
  std::string cmd = quote(program.string());
  for (const auto& a : args) cmd += " " + quote(a);
  cmd += " 2>&1";
  FILE* p = ::popen(cmd.c_str(), "r");
  if (!p) throw std::runtime_error("cannot run " + program.string());
  std::string out;
  std::array<char, 512> buf{};
  while (std::fgets(buf.data(), buf.size(), p)) out += buf.data();
  const int st = ::pclose(p);
  if (!WIFEXITED(st) || WEXITSTATUS(st) != 0) {
    std::string line = program.filename().string();
    for (const auto& a : args) line += " " + a;
    throw std::runtime_error(line + " failed: " + out);
  }
  return out;
}

std::string Controller::cnc(const std::vector<std::string>& args) const { return run(bin_ / "cnc", args); }

double Controller::getp(const std::string& name) const {
  const std::string out = run(bin_ / "halcmd", {"getp", name});
  try {
    return std::stod(out);
  } catch (const std::exception&) {
    throw std::runtime_error("halcmd getp " + name + ": not a number: " + out);
  }
}

double Controller::motor_position(int joint) const {
  const auto j = nlohmann::json::parse(cnc({"status", "--json"}));
  return j.at("joints").at(joint).at("motor_pos_fb").get<double>();
}

double Controller::servo_period_s() const {
  const auto j = nlohmann::json::parse(cnc({"status", "--json"}));
  for (const auto& t : j.value("threads", nlohmann::json::array()))
    if (t.value("name", std::string()) == "servo-thread" && t.value("period_ns", 0.0) > 0)
      return t["period_ns"].get<double>() * 1e-9;
  return 1e-3;
}

bool Controller::estop_chain_ok() const {
  const auto j = nlohmann::json::parse(cnc({"status", "--json"}));
  return j.at("io").value("estop_chain_ok", false);
}

ControllerProcess::ControllerProcess(const std::filesystem::path& bin_dir, const std::filesystem::path& ini,
                                     const std::filesystem::path& log)
    : bin_(bin_dir) {
  const std::string cmd = "exec " + quote((bin_dir / "cncd").string()) + " " + quote(ini.string()) + " > " +
                          quote(log.string()) + " 2>&1";
  const char* argv[] = {"/bin/sh", "-c", cmd.c_str(), nullptr};
  pid_t pid = -1;
  if (posix_spawn(&pid, "/bin/sh", nullptr, nullptr, const_cast<char**>(argv), environ) != 0)
    throw std::runtime_error("cannot start " + (bin_dir / "cncd").string());
  pid_ = pid;
  try {
    Controller(bin_dir).cnc({"--timeout", "30", "wait-ready"});
  } catch (const std::exception&) {
    stop();
    std::ifstream in(log);
    std::stringstream ss;
    ss << in.rdbuf();
    std::string text = ss.str();
    if (text.size() > 2000) text = "..." + text.substr(text.size() - 2000);
    throw std::runtime_error("cncd on " + ini.string() + " did not come up:\n" + text);
  }
}

ControllerProcess::~ControllerProcess() {
  if (pid_ > 0) stop();
}

int ControllerProcess::stop() {
  if (pid_ <= 0) return -1;
  try {
    Controller(bin_).cnc({"shutdown"});
  } catch (const std::exception&) {
    // Not answering: the signal below stops it.
  }
  int status = 0;
  for (int i = 0; i < 100; ++i) {
    if (::waitpid(pid_, &status, WNOHANG) == pid_) {
      pid_ = -1;
      return WIFEXITED(status) ? WEXITSTATUS(status) : -1;
    }
    std::this_thread::sleep_for(std::chrono::milliseconds(100));
  }
  ::kill(pid_, SIGTERM);
  ::waitpid(pid_, &status, 0);
  pid_ = -1;
  return -1;
}

void request_abort() noexcept { g_abort.store(true, std::memory_order_relaxed); }
std::string switch_off_after_failure(const Controller& c, bool abort_program) noexcept {
  try {
    try {
      if (abort_program) c.cnc({"abort"});
      c.cnc({"off"});
      return "; the machine is off again, the drives disabled";
    } catch (const std::exception& e) {
      // Already in E-stop (the controller's own stop): the drives are off.
      if (std::string(e.what()).find("in E-stop") != std::string::npos) return "; the machine is in E-stop, the drives disabled";
      return "; switching the machine off failed too (" + std::string(e.what()) + "): press E-stop";
    }
  } catch (...) {
    return "; switching the machine off failed too: press E-stop";
  }
}

bool abort_requested() noexcept { return g_abort.load(std::memory_order_relaxed); }
void clear_abort() noexcept { g_abort.store(false, std::memory_order_relaxed); }

void home_all(const Controller& c, const std::string& who, double timeout_s) {
  const ipc::Client client;
  auto all_homed = [&client]() {
    const ipc::Status st = client.status();
    for (int j = 0; j < st.motion.joints && j < kMaxJoints; ++j)
      if (!st.joints[j].homed) return false;
    return true;
  };
  if (all_homed()) return;
  c.cnc({"mode", "manual"});
  c.cnc({"home", "all"});
  const auto t0 = std::chrono::steady_clock::now();
  while (!all_homed()) {
    if (g_abort.load(std::memory_order_relaxed)) throw std::runtime_error(who + ": aborted while homing");
    if (std::chrono::steady_clock::now() - t0 > std::chrono::duration<double>(timeout_s)) {
      char b[64];
      std::snprintf(b, sizeof b, "%.0f s", timeout_s);
      throw std::runtime_error(who + ": homing did not end within " + b);
    }
    std::this_thread::sleep_for(std::chrono::milliseconds(50));
  }
}

JogResult direction_jog(const Controller& c, const Axis& a, double distance_mm, double velocity) {
  const std::vector<Axis> joints = step_joints(a);  // a gantry pair: both, jogged together
  double cap = direction_test_travel_limit(a);
  for (const Axis& j : joints) cap = std::min(cap, direction_test_travel_limit(j));
  const double dist = std::copysign(std::min(std::fabs(distance_mm), cap), distance_mm);
  const double vel = std::min(std::fabs(velocity), kMaxTestVelocity);
  if (!(std::fabs(dist) > 0) || !(vel > 0)) throw std::runtime_error("direction test: no travel or no speed given");
  g_abort.store(false, std::memory_order_relaxed);
  c.cnc({"estop-reset"});
  if (!c.estop_chain_ok())
    throw std::runtime_error(std::string("axis ") + a.letter + ": the E-stop chain is open: close it before a test move");
  c.cnc({"on"});
  c.cnc({"mode", "manual"});
  JogResult r;
  r.commanded_mm = dist;
  r.limited = std::fabs(distance_mm) > cap;
  std::vector<double> before, now;
  for (const Axis& j : joints) before.push_back(c.motor_position(j.joint));
  now = before;
  const auto stop_all = [&c, &joints]() {
    for (const Axis& j : joints) c.cnc({"jog-stop", std::to_string(j.joint)});
  };
  const auto moved = [&]() {
    std::string m;
    for (std::size_t i = 0; i < joints.size(); ++i)
      m += (i ? ", joint " : "moved ") + (i ? std::to_string(joints[i].joint) + " " : std::string()) +
           std::to_string(now[i] - before[i]) + " mm";
    return m + " of " + std::to_string(dist);
  };
  const auto limit = std::chrono::duration<double>(2 * std::fabs(dist) / vel + 3.0);
  const auto start = std::chrono::steady_clock::now();
  try {
    for (const Axis& j : joints) c.cnc({"jog", std::to_string(j.joint), std::to_string(vel), std::to_string(dist)});
    std::vector<double> last = before;
    int still = 0;
    for (;;) {
      std::this_thread::sleep_for(std::chrono::milliseconds(100));
      bool arrived = true;
      for (std::size_t i = 0; i < joints.size(); ++i) {
        now[i] = c.motor_position(joints[i].joint);
        arrived = arrived && std::fabs(now[i] - before[i] - dist) < 0.001 && std::fabs(now[i] - last[i]) < 1e-5;
      }
      still = arrived ? still + 1 : 0;
      if (still >= 3) break;
      last = now;
      if (g_abort.load(std::memory_order_relaxed)) {
        stop_all();
        throw std::runtime_error(std::string("axis ") + a.letter + ": the test move was aborted (" + moved() + ")");
      }
      if (std::chrono::steady_clock::now() - start > limit) {
        stop_all();
        throw std::runtime_error(std::string("axis ") + a.letter + ": the test move did not end within " +
                                 std::to_string(limit.count()) + " s (" + moved() + "): stopped");
      }
    }
    r.feedback_mm = c.motor_position(a.joint) - before[0];
    if (joints.size() > 1) r.gantry_feedback_mm = c.motor_position(joints[1].joint) - before[1];
  } catch (const std::exception& e) {
    // Whatever stopped the test, the drives end disabled.
    const std::string off = switch_off_after_failure(c);
    std::string why = e.what();
    if (g_abort.load(std::memory_order_relaxed) && why.find("aborted") == std::string::npos)
      why = std::string("axis ") + a.letter + ": the test move was aborted (" + why + ")";
    throw std::runtime_error(why + off);
  }
  c.cnc({"off"});
  return r;
}

}  // namespace cnc::commission
