#include "commission/check.hpp"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <sstream>
#include <stdexcept>
#include <thread>

#include "commission/homing_check.hpp"
#include "commission/steps.hpp"
#include "core/ipc/client.hpp"
#include "core/util/strings.hpp"

namespace cnc::commission {

namespace {

std::string num(double v) {
  char b[32];
  std::snprintf(b, sizeof b, "%.4f", v);
  std::string s = b;
  // Trailing zeros off: "12.5000" -> "12.5", "-0.0000" -> "0".
  while (s.back() == '0') s.pop_back();
  if (s.back() == '.') s.pop_back();
  return s == "-0" ? "0" : s;
}

// The pose index of an axis letter (X Y Z A B C U V W).
int pose_index(char letter) {
  static const std::string kLetters = "XYZABCUVW";
  const auto i = kLetters.find(letter);
  return i == std::string::npos ? -1 : static_cast<int>(i);
}

constexpr const char* kEndTag = "(cnc-commission end";

}  // namespace

double check_inset(const Axis& a) noexcept {
  return std::clamp(0.05 * (a.max_limit - a.min_limit), 0.5, 5.0);
}

double check_feed(const Axis& a) noexcept {
  const double v = a.tuning && a.tuning->max_velocity > 0 ? a.tuning->max_velocity : a.max_velocity;
  return std::min(0.25 * v, kCheckMaxFeed);
}

namespace {

// One axis' part of the check program: from where homing leaves it to a
// little inside each soft limit and back, at its check feed.
struct CheckLeg {
  const Axis* axis;
  double lo, hi, home, feed;
};

// The check program's legs, the axes in joint order.
std::vector<CheckLeg> check_legs(const State& s) {
  std::vector<const Axis*> axes;
  for (const Axis& a : s.axes) axes.push_back(&a);
  if (axes.empty()) throw std::invalid_argument("check program: no axis: assign a drive to an axis first");
  std::sort(axes.begin(), axes.end(), [](const Axis* a, const Axis* b) { return a->joint < b->joint; });
  std::vector<CheckLeg> legs;
  for (const Axis* a : axes) {
    // The soft limits as written, never onto a limit switch found.
    const Travel t = clear_of_switches(*a, {a->min_limit, a->max_limit, "the soft limits"});
    const double inset = check_inset(*a);
    const double lo = t.min + inset, hi = t.max - inset, home = written_home(*a);
    if (!(lo < hi))
      throw std::invalid_argument(std::string("check program: axis ") + a->letter + ": the soft limits " +
                                  num(a->min_limit) + ".." + num(a->max_limit) + " mm leave no travel");
    const double feed = check_feed(*a);
    if (!(feed > 0)) throw std::invalid_argument(std::string("check program: axis ") + a->letter + ": no velocity");
    legs.push_back({a, lo, hi, home, feed});
  }
  return legs;
}

}  // namespace

double check_program_seconds(const State& s) {
  double t = 0;
  for (const CheckLeg& l : check_legs(s))
    t += (std::fabs(l.home - l.lo) + (l.hi - l.lo) + std::fabs(l.hi - l.home)) / l.feed;
  return t;
}

double check_default_timeout_s(double program_s) noexcept { return std::max(600.0, 2 * program_s + 60); }

std::string check_program(const State& s) {
  const std::vector<CheckLeg> legs = check_legs(s);
  std::ostringstream g, end;
  for (const CheckLeg& l : legs) end << " " << l.axis->letter << num(l.home);
  g << "(cnc-commission check program for " << s.machine << ", written with the configuration:)\n"
    << "(each axis alone to a little inside its soft limits and back to where)\n"
    << "(homing leaves it, at a quarter of its speed, at most " << num(kCheckMaxFeed) << " mm/s.)\n"
    << kEndTag << end.str() << ")\n"
    << "G21 G90 G94 G17 G40 G49 G80\n";
  for (const CheckLeg& l : legs) {
    const char letter = l.axis->letter;
    g << "(axis " << letter << ": " << num(l.lo) << " .. " << num(l.hi) << " mm, back to " << num(l.home) << ")\n"
      << "G53 G1 " << letter << num(l.lo) << " F" << num(l.feed * 60) << "\n"
      << "G53 G1 " << letter << num(l.hi) << "\n"
      << "G53 G1 " << letter << num(l.home) << "\n";
  }
  g << "M2\n";
  return g.str();
}

std::vector<std::pair<char, double>> declared_end(const std::string& text, const std::string& origin) {
  std::vector<std::pair<char, double>> out;
  std::istringstream in(text);
  std::string line;
  int n = 0;
  while (std::getline(in, line)) {
    ++n;
    const auto at = line.find(kEndTag);
    if (at == std::string::npos) continue;
    const auto close = line.find(')', at);
    const std::string where = origin + ":" + std::to_string(n) + ": ";
    if (close == std::string::npos) throw std::invalid_argument(where + "the end comment has no ')'");
    for (const auto& w : split(line.substr(at + std::string(kEndTag).size(), close - at - std::string(kEndTag).size()), ' ')) {
      const std::string word(trim(w));
      if (word.empty()) continue;
      const char letter = static_cast<char>(std::toupper(static_cast<unsigned char>(word[0])));
      const auto v = parse_double(word.substr(1));
      if (pose_index(letter) < 0 || !v)
        throw std::invalid_argument(where + "\"" + word + "\": expected an axis letter and a position, e.g. X0 or Z-5");
      out.emplace_back(letter, *v);
    }
    if (out.empty()) throw std::invalid_argument(where + "the end comment names no axis");
    return out;
  }
  return out;
}

std::string run_check(const Controller& c, const std::filesystem::path& program, double timeout_s,
                      const std::function<void(int, int, const std::string&)>& progress) {
  using clock = std::chrono::steady_clock;
  const std::string who = "check";
  auto say = [&](int i, const std::string& t) { if (progress) progress(i, 5, t); };
  std::string text;
  {
    std::FILE* f = std::fopen(program.c_str(), "r");
    if (!f) throw std::runtime_error(program.string() + ": cannot read the check program");
    char buf[4096];
    std::size_t n;
    while ((n = std::fread(buf, 1, sizeof buf, f)) > 0) text.append(buf, n);
    std::fclose(f);
  }
  const auto end = declared_end(text, program.string());
  clear_abort();
  const ipc::Client client;
  std::string report;
  try {
    say(1, "E-stop reset, machine on");
    c.cnc({"estop-reset"});
    if (!c.estop_chain_ok()) throw std::runtime_error(who + ": the E-stop chain is open: close it before the check");
    c.cnc({"on"});
    say(2, "homing every joint");
    home_all(c, who);
    say(3, "running " + program.string());
    c.cnc({"mode", "auto"});
    c.cnc({"open", std::filesystem::absolute(program).string()});
    c.cnc({"run"});
    const auto start = clock::now();
    bool seen_running = false;
    ipc::Status st;
    for (;;) {
      std::this_thread::sleep_for(std::chrono::milliseconds(50));
      st = client.status();
      const bool running = st.task.interp_state != ipc::InterpState::Idle;
      seen_running = seen_running || running;
      const double t = std::chrono::duration<double>(clock::now() - start).count();
      if (abort_requested()) throw std::runtime_error(who + ": aborted at line " + std::to_string(st.task.current_line));
      if (st.task.state != ipc::TaskState::On)
        throw std::runtime_error(who + ": the machine went off at line " + std::to_string(st.task.current_line) + " of " +
                                 program.string() + " (E-stop, a following error, a drive fault: see cnc messages)");
      if (t > timeout_s)
        throw std::runtime_error(who + ": the program did not end within " + num(timeout_s) + " s (at line " +
                                 std::to_string(st.task.current_line) + ")");
      if (!running && (seen_running || t > 2)) break;
    }
    if (st.task.errors_since_start != 0)
      throw std::runtime_error(who + ": the program ended with " + std::to_string(st.task.errors_since_start) +
                               " error(s) (see cnc messages)");
    say(4, "checking the end position");
    std::string missed, at;
    for (const auto& [letter, want] : end) {
      const double got = st.motion.position[pose_index(letter)];
      at += std::string(at.empty() ? "" : " ") + letter + num(got);
      if (std::fabs(got - want) > 0.001)
        missed += std::string(missed.empty() ? "" : ", ") + letter + " at " + num(got) + " mm instead of " + num(want);
    }
    if (!missed.empty()) throw std::runtime_error(who + ": the program ended off its declared end position: " + missed);
    char secs[32];
    std::snprintf(secs, sizeof secs, "%.1f s", std::chrono::duration<double>(clock::now() - start).count());
    report = std::string("the program ran to its end in ") + secs +
             (end.empty() ? " (it declares no end position)" : ", ending at " + at + " as declared");
  } catch (const std::exception& e) {
    throw std::runtime_error(e.what() + switch_off_after_failure(c, /*abort_program=*/true));
  }
  c.cnc({"off"});
  say(5, "machine off");
  return report;
}

}  // namespace cnc::commission
