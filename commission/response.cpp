#include "commission/response.hpp"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <complex>
#include <cstdio>
#include <fstream>
#include <nlohmann/json.hpp>
#include <sstream>
#include <stdexcept>
#include <thread>

#include "commission/steps.hpp"
#include "commission/tuning.hpp"
#include "core/ipc/segment.hpp"
#include "core/util/atomic_file.hpp"
#include "core/util/strings.hpp"
#include "commission/restore.hpp"
#include "fieldbus/can/transport.hpp"
#include "fieldbus/ethercat/master.hpp"

namespace cnc::commission {

namespace {

std::string fmt(const char* f, double v) {
  char b[64];
  std::snprintf(b, sizeof b, f, v);
  return b;
}

std::string axis_name(const Axis& a) { return std::string("axis ") + a.letter; }

double mean(const std::vector<double>& v) {
  double s = 0;
  for (double x : v) s += x;
  return v.empty() ? 0 : s / static_cast<double>(v.size());
}

}  // namespace

// ---- records ----

std::string response_csv(const std::vector<ResponseSample>& samples, double frequency_hz) {
  std::string out;
  char b[160];
  for (const ResponseSample& s : samples) {
    std::snprintf(b, sizeof b, "%.4f,%.6f,%.5f,%.5f,%.2f\n", frequency_hz, s.time_s, s.vel_cmd_mm_s, s.velocity_mm_s,
                  s.torque_pct);
    out += b;
  }
  return out;
}

const char* loop_name(Loop l) noexcept { return l == Loop::Position ? "position" : "velocity"; }

std::vector<ResponseSample> load_response_csv(const std::filesystem::path& file, std::vector<double>* frequency_hz,
                                              Loop* loop) {
  std::ifstream in(file);
  if (!in) throw std::runtime_error(file.string() + ": cannot be read");
  std::string line;
  if (!std::getline(in, line)) line.clear();
  const std::string header(trim(line));
  if (header != kResponseCsvHeader && header != kPositionResponseCsvHeader)
    throw std::runtime_error(file.string() + ":1: expected the header " + kResponseCsvHeader + " (or, of the position loop, " +
                             kPositionResponseCsvHeader + ")");
  if (loop) *loop = header == kPositionResponseCsvHeader ? Loop::Position : Loop::Velocity;
  const auto names = split(header, ',');
  std::vector<ResponseSample> out;
  int n = 1;
  while (std::getline(in, line)) {
    ++n;
    if (trim(line).empty()) continue;
    const auto w = split(std::string(trim(line)), ',');
    if (w.size() != names.size())
      throw std::runtime_error(file.string() + ":" + std::to_string(n) + ": " + std::to_string(w.size()) + " columns, expected " +
                               std::to_string(names.size()));
    double v[5];
    for (std::size_t k = 0; k < names.size(); ++k) {
      const auto d = parse_double(trim(w[k]));
      if (!d)
        throw std::runtime_error(file.string() + ":" + std::to_string(n) + ": column " + names[k] + ": \"" + w[k] +
                                 "\" is not a number");
      v[k] = *d;
    }
    if (frequency_hz) frequency_hz->push_back(v[0]);
    out.push_back({v[1], v[2], v[3], v[4]});
  }
  return out;
}

std::vector<std::string> response_scope_pins(int drive, Loop loop) {
  char d[40];
  std::snprintf(d, sizeof d, "cia402.0.drive.%02d.", drive);
  if (loop == Loop::Position) return {std::string(d) + "pos-cmd", std::string(d) + "pos-fb", std::string(d) + "torque"};
  return {std::string(d) + "vel-cmd", std::string(d) + "vel-fb", std::string(d) + "torque"};
}

std::vector<ResponseSample> parse_response_scope_csv(const std::string& text) {
  std::istringstream in(text);
  std::string line;
  if (!std::getline(in, line)) throw std::runtime_error("scope csv: empty");
  if (split(std::string(trim(line)), ',').size() != 4)
    throw std::runtime_error("scope csv: unexpected header \"" + line + "\" (time_s and the 3 response pins)");
  std::vector<ResponseSample> out;
  int n = 1;
  while (std::getline(in, line)) {
    ++n;
    if (trim(line).empty()) continue;
    const auto w = split(std::string(trim(line)), ',');
    double v[4];
    if (w.size() != 4) throw std::runtime_error("scope csv:" + std::to_string(n) + ": expected 4 columns");
    for (int k = 0; k < 4; ++k) {
      const auto d = parse_double(trim(w[k]));
      if (!d) throw std::runtime_error("scope csv:" + std::to_string(n) + ": \"" + w[k] + "\" is not a number");
      v[k] = *d;
    }
    out.push_back({v[0], v[1], v[2], v[3]});
  }
  return out;
}

// ---- analysis ----

StepResponse analyse_step(const std::vector<ResponseSample>& s, double band, double min_hold_s) {
  if (s.size() < 3) throw std::invalid_argument("step response: fewer than 3 samples");
  double lo = s[0].vel_cmd_mm_s, hi = lo;
  for (const ResponseSample& x : s) {
    lo = std::min(lo, x.vel_cmd_mm_s);
    hi = std::max(hi, x.vel_cmd_mm_s);
  }
  const double span = hi - lo;
  std::vector<std::size_t> edges;
  for (std::size_t i = 1; span > 0 && i < s.size(); ++i)
    if (std::fabs(s[i].vel_cmd_mm_s - s[i - 1].vel_cmd_mm_s) > 0.75 * span) edges.push_back(i);
  std::vector<double> rise, overshoot, settle;
  for (std::size_t e = 0; e < edges.size(); ++e) {
    const std::size_t i = edges[e], end = e + 1 < edges.size() ? edges[e + 1] : s.size();
    if (s[end - 1].time_s - s[i].time_s < min_hold_s) continue;
    const double v0 = s[i - 1].vel_cmd_mm_s, v1 = s[i].vel_cmd_mm_s, t0 = s[i].time_s;
    auto y = [&](std::size_t k) { return (s[k].velocity_mm_s - v0) / (v1 - v0); };
    // Crossing times, interpolated between samples.
    auto crossing = [&](double level) {
      for (std::size_t k = i; k < end; ++k)
        if (y(k) >= level) {
          const double ya = y(k - 1), yb = y(k);
          const double f = yb > ya ? std::clamp((level - ya) / (yb - ya), 0.0, 1.0) : 1.0;
          return s[k - 1].time_s + f * (s[k].time_s - s[k - 1].time_s);
        }
      return -1.0;
    };
    const double t10 = crossing(0.1), t90 = crossing(0.9);
    if (t10 < 0 || t90 < 0) continue;  // never rose: not a step this record can say anything of
    double peak = 0;
    std::size_t last_out = i;
    for (std::size_t k = i; k < end; ++k) {
      peak = std::max(peak, y(k));
      if (std::fabs(y(k) - 1.0) > band) last_out = k;
    }
    rise.push_back(t90 - t10);
    overshoot.push_back(std::max(0.0, peak - 1.0) * 100.0);
    settle.push_back(last_out + 1 < end ? s[last_out + 1].time_s - t0 : -1.0);
  }
  if (rise.empty())
    throw std::invalid_argument("step response: no edge of the command followed by a rise of the velocity (" +
                                std::to_string(edges.size()) + " edges)");
  StepResponse r;
  r.amplitude_mm_s = span / 2;
  r.edges = static_cast<int>(rise.size());
  r.rise_time_s = mean(rise);
  r.overshoot_pct = mean(overshoot);
  r.settling_time_s = std::any_of(settle.begin(), settle.end(), [](double t) { return t < 0; }) ? -1 : mean(settle);
  return r;
}

FrequencyPoint analyse_sine(const std::vector<ResponseSample>& s, double f) {
  if (s.size() < 4 || !(f > 0)) throw std::invalid_argument("sine response: no samples or no frequency");
  const double t_end = s.back().time_s;
  const double cycles = std::floor((t_end - s.front().time_s) * f + 1e-6);
  if (cycles < 1) throw std::invalid_argument("sine response at " + fmt("%g", f) + " Hz: less than one cycle recorded");
  const double t_start = t_end - cycles / f;
  std::complex<double> u(0), y(0);
  double mu = 0, my = 0;
  int n = 0;
  for (const ResponseSample& x : s)
    if (x.time_s > t_start + 1e-9) {
      mu += x.vel_cmd_mm_s;
      my += x.velocity_mm_s;
      ++n;
    }
  mu /= n;
  my /= n;
  const double w = 2 * M_PI * f;
  for (const ResponseSample& x : s)
    if (x.time_s > t_start + 1e-9) {
      const std::complex<double> e = std::polar(1.0, -w * x.time_s);
      u += (x.vel_cmd_mm_s - mu) * e;
      y += (x.velocity_mm_s - my) * e;
    }
  if (std::abs(u) == 0) throw std::invalid_argument("sine response at " + fmt("%g", f) + " Hz: the command does not move");
  const std::complex<double> h = y / u;
  FrequencyPoint p;
  p.frequency_hz = f;
  p.gain_db = 20 * std::log10(std::max(std::abs(h), 1e-12));
  p.phase_deg = std::arg(h) * 180 / M_PI;
  return p;
}

double bandwidth_hz(std::vector<FrequencyPoint>& p, bool& above) {
  above = false;
  if (p.empty()) throw std::invalid_argument("bandwidth: no frequency point");
  for (std::size_t i = 1; i < p.size(); ++i) {  // phase lag grows with frequency: unwrap
    while (p[i].phase_deg - p[i - 1].phase_deg > 180) p[i].phase_deg -= 360;
    while (p[i].phase_deg - p[i - 1].phase_deg < -180) p[i].phase_deg += 360;
  }
  const double level = p.front().gain_db - 3.0;
  for (std::size_t i = 1; i < p.size(); ++i)
    if (p[i].gain_db < level) {
      const double a = std::log(p[i - 1].frequency_hz), b = std::log(p[i].frequency_hz);
      const double f = (level - p[i - 1].gain_db) / (p[i].gain_db - p[i - 1].gain_db);
      return std::exp(a + f * (b - a));
    }
  above = true;
  return p.back().frequency_hz;
}

// ---- the drive's gains, by SDO or CoE SDO ----

namespace {

template <class T>
T value_of(const DriveChannel::Result& r) {
  T v = 0;
  for (std::size_t i = 0; i < sizeof(T) && i < r.data.size(); ++i) v = static_cast<T>(v | (T(r.data[i]) << (8 * i)));
  return v;
}

}  // namespace

std::optional<LoopGains> read_loop_gains(DriveChannel& drive, const std::string& who, std::string& why) {
  LoopGains g;
  const auto kv = drive.upload({0x60F9, 1});
  if (!kv.ok) {
    why = who + " has no readable velocity control parameter set 0x60F9 (" + kv.error + ")";
    return std::nullopt;
  }
  g.velocity_gain = value_of<uint32_t>(kv);
  const auto ti = drive.upload({0x60F9, 2});
  if (ti.ok) g.velocity_integral = value_of<uint16_t>(ti);
  const auto kp = drive.upload({0x60FB, 1});
  if (kp.ok) g.position_gain = value_of<uint32_t>(kp);
  return g;
}

void write_velocity_gain(DriveChannel& drive, const std::string& who, uint32_t gain) {
  std::vector<uint8_t> d(4);
  for (int i = 0; i < 4; ++i) d[i] = static_cast<uint8_t>(gain >> (8 * i));
  const auto r = drive.download({0x60F9, 1}, d);
  if (!r.ok)
    throw std::runtime_error(who + ": writing the velocity gain " + std::to_string(gain) + " to 0x60F9:01 failed: " + r.error);
}

namespace {

std::optional<LoopGains> gains_of(DriveChannel& drive, const std::string& who, std::optional<uint32_t> velocity_gain,
                                  std::string& why, DriveFound& found) {
  if (velocity_gain) {
    // A drive without a readable 0x60F9 is skipped, not written to.
    const auto before = read_loop_gains(drive, who, why);
    if (!before) return std::nullopt;
    if (before->velocity_gain != *velocity_gain) {
      found.velocity_gain = before->velocity_gain;  // noted before the write: a refused write is put back too
      write_velocity_gain(drive, who, *velocity_gain);
    }
  }
  return read_loop_gains(drive, who, why);
}

std::string who_of(const Axis& a) {
  return a.slave != 0 ? "EtherCAT slave " + std::to_string(a.slave) : "node " + std::to_string(a.node);
}

// `work` on axis `a`'s EtherCAT slave through this program's own master,
// the slaves in PREOP, back to INIT afterwards (the next master brings them
// up from there).
template <class Work>
void on_ethercat_slave(const State& s, const Axis& a, Work&& work) {
  if (s.ethercat_interface.empty())
    throw std::runtime_error(axis_name(a) + ": no EtherCAT segment in the state (scan-ethercat first)");
  ethercat::MasterConfig cfg;
  cfg.interface = s.ethercat_interface;
  ethercat::Master m(cfg, nullptr);
  try {
    m.to_preop();
    work(*ethercat_channel(m, static_cast<unsigned>(a.slave)));
  } catch (const std::exception& e) {
    m.release();
    throw std::runtime_error(s.ethercat_interface + ": " + e.what());
  }
  m.release();
}

}  // namespace

std::optional<LoopGains> response_gains(const State& s, const Axis& a, std::optional<uint32_t> velocity_gain,
                                        std::string& why, DriveFound& found) {
  if (a.slave == 0) {
    auto bus = can::open_transport(response_sdo_interface(s));
    const auto drive = canopen_channel(*bus, a.node, 1'000'000'000);
    return gains_of(*drive, who_of(a), velocity_gain, why, found);
  }
  std::optional<LoopGains> g;
  on_ethercat_slave(s, a, [&](DriveChannel& drive) {
    // The response controller's drive layer writes its modes to 0x6060 (by
    // CoE: the ESI's RxPDO does not map it); the next controller finds
    // the mode this one found.
    const auto mode = drive.upload({0x6060, 0});
    if (mode.ok && !mode.data.empty()) found.mode = static_cast<int8_t>(mode.data[0]);
    g = gains_of(drive, who_of(a), velocity_gain, why, found);
  });
  return g;
}

void wait_node_operational(const Controller& c, const Axis& a, double timeout_s) {
  char pin[48];
  std::snprintf(pin, sizeof pin, "canopen.0.node.%02u.operational", static_cast<unsigned>(a.node));
  const auto until = std::chrono::steady_clock::now() + std::chrono::duration<double>(timeout_s);
  for (;;) {
    const std::string v(trim(c.halcmd({"getp", pin})));
    if (v == "TRUE") return;
    if (std::chrono::steady_clock::now() > until)
      throw std::runtime_error(who_of(a) + ": not operational " + fmt("%g", timeout_s) + " s after the response controller started (" +
                               pin + " " + v + "): check the node's boot in cncd.log");
    if (abort_requested()) throw std::runtime_error(axis_name(a) + ": the response test was aborted");
    std::this_thread::sleep_for(std::chrono::milliseconds(50));
  }
}

void restore_drive(DriveChannel& drive, const std::string& who, const DriveFound& found) {
  auto put_back = [&](canopen::ObjectAddress o, std::vector<uint8_t> value, const std::string& what) {
    char obj[16];
    std::snprintf(obj, sizeof obj, "0x%04X:%02X", o.index, o.sub);
    const auto w = drive.download(o, value);
    if (!w.ok) throw std::runtime_error(who + ": putting back " + what + " to " + obj + " failed: " + w.error);
    auto r = drive.upload(o);
    if (r.ok) r.data.resize(value.size(), 0);
    if (!r.ok || r.data != value)
      throw std::runtime_error(who + ": " + what + " written back to " + obj + " does not read back (" +
                               (r.ok ? "another value" : r.error) + ")");
  };
  if (found.velocity_gain) {
    std::vector<uint8_t> d(4);
    for (int i = 0; i < 4; ++i) d[i] = static_cast<uint8_t>(*found.velocity_gain >> (8 * i));
    put_back({0x60F9, 1}, d, "the velocity gain " + std::to_string(*found.velocity_gain));
  }
  if (found.mode) put_back({0x6060, 0}, {static_cast<uint8_t>(*found.mode)}, "the mode of operation " + std::to_string(*found.mode));
}

void restore_drive(const State& s, const Axis& a, const DriveFound& found) {
  if (!found.changed()) return;
  if (a.slave == 0) {
    auto bus = can::open_transport(response_sdo_interface(s));
    const auto drive = canopen_channel(*bus, a.node, 1'000'000'000);
    restore_drive(*drive, who_of(a), {found.velocity_gain, std::nullopt});
    return;
  }
  on_ethercat_slave(s, a, [&](DriveChannel& drive) { restore_drive(drive, who_of(a), found); });
}

// ---- the configuration ----

std::vector<GeneratedFile> response_configuration(const State& s, char letter, const std::filesystem::path& dir,
                                                  const std::string& name) {
  const Axis* a = s.axis(letter);
  if (!a) throw std::invalid_argument(std::string("axis ") + letter + " has no drive yet");
  TuneOptions t;
  t.max_velocity = std::max(a->max_velocity, 1.0);
  t.max_acceleration = std::max(a->max_acceleration, 10.0);
  State r = tuning_configuration(s, letter, t);
  // Motion's command stands while the drive runs in CSV: its following
  // error is the excursion, which run_response keeps under 1 mm.
  r.axis(letter)->tuning->min_ferror = 3;
  r.axis(letter)->tuning->ferror = std::max(r.axis(letter)->tuning->ferror, 4.0);
  WriterOptions w;
  w.response_axis = letter;
  return generate_config(r, dir, name, w);
}

std::string response_sdo_interface(const State& s) {
  const std::string& i = s.interface;
  if (i.rfind("virtual:", 0) == 0) {
    const std::string name = i.substr(8, i.find(',') == std::string::npos ? std::string::npos : i.find(',') - 8);
    return "unix:/dev/shm/cnc-" + ipc::default_instance() + ".can-" + name;
  }
  return i;
}

// ---- the tests on a controller ----

namespace {

struct Now {
  double pos = 0;
  bool enabled = false, on = false, fault = false;
};

Now now_of(const Controller& c, int joint) {
  const auto j = nlohmann::json::parse(c.cnc({"status", "--json"}));
  const auto& js = j.at("joints").at(joint);
  Now n;
  n.pos = js.at("pos_fb").get<double>();
  n.fault = js.value("fault", false);
  n.enabled = j.at("motion").value("enabled", false);
  n.on = j.at("task").value("state", std::string()) == "ON";
  return n;
}

class Session {
 public:
  Session(const Controller& c, const Axis& a, const ResponseOptions& o, double start, double period)
      : c_(c), a_(a), o_(o), start_(start), period_(period),
        gen_(o.loop == Loop::Position ? "response-pos" : "response") {
    std::snprintf(drive_, sizeof drive_, "cia402.0.drive.%02d.", a.joint);
  }
  // On, the generator quiet; the velocity loop: CSV. The drive's mode
  // request and mode as found are noted for end().
  void begin() {
    quiet();
    if (o_.loop == Loop::Position) {  // CSP as the controller runs it
      c_.cnc({"on"});
      c_.cnc({"mode", "manual"});
      return;
    }
    if (!found_) {
      request_before_ = static_cast<int>(c_.getp(std::string(drive_) + "mode-request"));
      mode_before_ = static_cast<int>(c_.getp(std::string(drive_) + "mode-display"));
      found_ = true;
    }
    c_.cnc({"on"});
    c_.cnc({"mode", "manual"});
    setp(std::string(drive_) + "mode-request", "9");
    wait_mode(9);
  }
  // The generator quiet, off (motion takes the feedback as its command),
  // and the drive back in the mode it was found in, before the next test
  // or the controller's end.
  void end() {
    quiet();
    std::this_thread::sleep_for(std::chrono::milliseconds(50));
    c_.cnc({"off"});
    if (!found_) return;  // the position loop: the mode untouched
    setp(std::string(drive_) + "mode-request", std::to_string(request_before_));
    if (mode_before_ > 0) wait_mode(mode_before_);  // 0: the drive had not shown its mode yet
  }
  // After a failure (the machine already off): the mode as found, as far
  // as the controller still answers. Never throws; "" or why not.
  std::string end_after_failure() noexcept {
    try {
      setp(gen_ + ".amplitude", "0");
      if (!found_) return {};  // not begun, or the position loop: the mode untouched
      setp(std::string(drive_) + "mode-request", std::to_string(request_before_));
      if (mode_before_ > 0) wait_mode(mode_before_, false);
    } catch (const std::exception& e) {
      return std::string("; the drive's mode was not put back: ") + e.what();
    }
    return {};
  }
  // The generator at `frequency`, square or sine, its amplitude the
  // options' (the velocity loop's sign against the excursion so far);
  // records `seconds` after `settle_s`.
  std::vector<ResponseSample> record(bool square, double frequency, double settle_s, double seconds) {
    check();
    double amplitude = o_.amplitude_mm;
    if (o_.loop == Loop::Velocity) {
      const double here = now_of(c_, a_.joint).pos - start_;
      amplitude = here > 0 ? -o_.amplitude_mm_s : o_.amplitude_mm_s;
    }
    setp(gen_ + "-mux.sel", square ? "1" : "0");
    setp(gen_ + ".frequency", fmt("%.6f", frequency));
    const auto samples = std::min(60000L, static_cast<long>(std::ceil(seconds / period_)) + 1);
    std::string list;
    for (const auto& p : response_scope_pins(a_.joint, o_.loop)) list += (list.empty() ? "" : ",") + p;
    c_.halcmd({"scope", "stop"});
    c_.halcmd({"scope", "setup", list, "samples=" + std::to_string(samples), "pre=0", "mode=single"});
    if (square) c_.halcmd({"scope", "arm"});
    setp(gen_ + ".amplitude", fmt("%.6f", amplitude));
    setp(gen_ + ".reset", "0");
    sleep_checked(settle_s);
    if (!square) c_.halcmd({"scope", "arm"});
    const auto until = std::chrono::steady_clock::now() + std::chrono::duration<double>(seconds * 3 + 5);
    while (std::string(trim(c_.halcmd({"scope", "state"}))).rfind("done", 0) != 0) {
      if (std::chrono::steady_clock::now() > until) throw std::runtime_error("the scope did not finish its capture");
      sleep_checked(0.05);
    }
    quiet();
    check();
    return parse_response_scope_csv(c_.halcmd({"scope", "csv"}));
  }

 private:
  void quiet() const {
    setp(gen_ + ".amplitude", "0");
    setp(gen_ + ".reset", "1");
  }
  void setp(const std::string& pin, const std::string& v) const { c_.halcmd({"setp", pin, v}); }
  // `abortable` false: after a failure or an abort, the mode is still
  // put back.
  void wait_mode(int mode, bool abortable = true) {
    const auto until = std::chrono::steady_clock::now() + std::chrono::seconds(3);
    while (static_cast<int>(c_.getp(std::string(drive_) + "mode-display")) != mode) {
      if (std::chrono::steady_clock::now() > until)
        throw std::runtime_error(axis_name(a_) + ": the drive did not switch to mode " + std::to_string(mode) +
                                 " within 3 s (mode-display " +
                                 fmt("%.0f", c_.getp(std::string(drive_) + "mode-display")) + ")");
      if (abortable) sleep_checked(0.02);
      else std::this_thread::sleep_for(std::chrono::milliseconds(20));
    }
  }
  void sleep_checked(double s) {
    const auto until = std::chrono::steady_clock::now() + std::chrono::duration<double>(s);
    while (std::chrono::steady_clock::now() < until) {
      if (abort_requested()) throw std::runtime_error(axis_name(a_) + ": the response test was aborted");
      std::this_thread::sleep_for(std::chrono::milliseconds(10));
    }
  }
  // The E-stop chain, motion and the excursion, between records.
  void check() {
    if (abort_requested()) throw std::runtime_error(axis_name(a_) + ": the response test was aborted");
    if (!c_.estop_chain_ok()) throw std::runtime_error(axis_name(a_) + ": the E-stop chain opened");
    const Now n = now_of(c_, a_.joint);
    if (!n.on || !n.enabled || n.fault)
      throw std::runtime_error(axis_name(a_) + ": motion stopped during the response test (a fault, E-stop)");
    if (std::fabs(n.pos - start_) > o_.max_excursion_mm)
      throw std::runtime_error(axis_name(a_) + ": the axis wandered " + fmt("%.3f", n.pos - start_) +
                               " mm from where the test started (at most " + fmt("%g", o_.max_excursion_mm) +
                               " mm): stopped");
  }

  const Controller& c_;
  const Axis& a_;
  const ResponseOptions& o_;
  double start_, period_;
  std::string gen_;  // the signal generator: "response" or "response-pos"
  char drive_[40];
  bool found_ = false;
  int request_before_ = 0, mode_before_ = 8;  // the drive layer's mode-request, the drive's mode
};

}  // namespace

AxisResponse run_response(const Controller& c, const Axis& a, const ResponseOptions& o) {
  const bool position = o.loop == Loop::Position;
  if (!position && !(o.amplitude_mm_s > 0 && o.amplitude_mm_s <= kMaxResponseAmplitude))
    throw std::invalid_argument(axis_name(a) + ": --amplitude " + fmt("%g", o.amplitude_mm_s) + ": expected 0 to " +
                                fmt("%g", kMaxResponseAmplitude) + " mm/s");
  if (position && !(o.amplitude_mm > 0 && o.amplitude_mm <= kMaxPositionResponseAmplitude))
    throw std::invalid_argument(axis_name(a) + ": --amplitude " + fmt("%g", o.amplitude_mm) + ": expected 0 to " +
                                fmt("%g", kMaxPositionResponseAmplitude) + " mm on the position loop");
  if (!(o.step_period_s >= 0.02 && o.step_period_s <= 5)) throw std::invalid_argument("response: step period 0.02 to 5 s");
  if (o.step_edges < 1 || o.step_edges > 50) throw std::invalid_argument("response: 1 to 50 step edges");
  if (o.frequencies < 2 || o.frequencies > 40) throw std::invalid_argument("response: 2 to 40 frequencies");
  if (!(o.min_frequency_hz > 0)) throw std::invalid_argument("response: the lowest frequency must be > 0");
  // The excursion of the tests: the velocity loop's a square's half
  // period, a sine's 2A/w; the position loop's its amplitude.
  const double excursion =
      position ? o.amplitude_mm
               : std::max(o.amplitude_mm_s * o.step_period_s / 2, o.amplitude_mm_s / (M_PI * o.min_frequency_hz));
  if (excursion > o.max_excursion_mm)
    throw std::invalid_argument(axis_name(a) + ": amplitude " + (position ? fmt("%g", o.amplitude_mm) + " mm" : fmt("%g", o.amplitude_mm_s) + " mm/s") + " would move the axis " +
                                fmt("%.2f", excursion) + " mm (at most " + fmt("%g", o.max_excursion_mm) +
                                "): lower --amplitude or raise the lowest frequency");
  const Travel travel = known_travel(a);
  auto progress = [&](const std::string& s) { if (o.progress) o.progress(s); };
  auto report = [&](const std::string& s) { if (o.report) o.report(s); };
  std::filesystem::create_directories(o.record_dir);

  clear_abort();
  c.cnc({"estop-reset"});
  if (!c.estop_chain_ok())
    throw std::runtime_error(axis_name(a) + ": the E-stop chain is open: close it before the response test");
  AxisResponse result;
  std::optional<Session> session;
  try {
    const double period = c.servo_period_s();
    const double f_max = o.max_frequency_hz > 0 ? std::min(o.max_frequency_hz, 0.2 / period) : 0.2 / period;
    if (!(f_max > o.min_frequency_hz)) throw std::invalid_argument("response: the highest frequency is below the lowest");
    const double start = now_of(c, a.joint).pos;
    if (start < travel.min + 2 * o.max_excursion_mm || start > travel.max - 2 * o.max_excursion_mm)
      throw std::runtime_error(axis_name(a) + " stands at " + fmt("%.3f", start) + " mm, closer than " +
                               fmt("%g", 2 * o.max_excursion_mm) + " mm to the end of its travel " + fmt("%g", travel.min) +
                               ".." + fmt("%g", travel.max) + " mm (" + travel.source + "): jog it inside first");
    session.emplace(c, a, o, start, period);
    const std::string l = std::string(1, static_cast<char>(std::tolower(a.letter))) + (position ? "-position" : "");
    const double amplitude = position ? o.amplitude_mm : o.amplitude_mm_s;
    const std::string unit = position ? " mm" : " mm/s";
    const std::string prefix = position ? "position " : "";  // the velocity loop's lines as they always were
    const std::string header = std::string(position ? kPositionResponseCsvHeader : kResponseCsvHeader) + "\n";
    const int total = (o.step ? 1 : 0) + (o.chirp ? o.frequencies : 0);
    int index = 0;
    if (o.step) {
      progress(std::to_string(++index) + "/" + std::to_string(total) + " " + prefix + "step: +-" +
               fmt("%g", amplitude) + unit + " every " + fmt("%g", o.step_period_s / 2) + " s");
      session->begin();
      const auto record = session->record(true, 1.0 / o.step_period_s, 0, o.step_period_s * (o.step_edges + 1) / 2);
      session->end();
      StepResponse step = analyse_step(record);
      step.csv = (o.record_dir / (l + "-response-step.csv")).string();
      write_file_atomically(step.csv, header + response_csv(record, 0));
      step.amplitude_mm_s = amplitude;
      report(prefix + "step: rise " + fmt("%.1f", step.rise_time_s * 1000) + " ms, overshoot " + fmt("%.1f", step.overshoot_pct) +
             " %, settling " +
             (step.settling_time_s < 0 ? std::string("not within the step") : fmt("%.1f", step.settling_time_s * 1000) + " ms") +
             " (" + std::to_string(step.edges) + " edges, " + step.csv + ")");
      (position ? result.position_step : result.step) = step;
    }
    if (o.chirp) {
      ChirpResponse chirp;
      chirp.amplitude_mm_s = amplitude;
      chirp.csv = (o.record_dir / (l + "-response-chirp.csv")).string();
      std::string csv = header;
      session->begin();
      for (int k = 0; k < o.frequencies; ++k) {
        const double f = o.min_frequency_hz * std::pow(f_max / o.min_frequency_hz, static_cast<double>(k) / (o.frequencies - 1));
        progress(std::to_string(++index) + "/" + std::to_string(total) + " " + prefix + "sine: " +
                 fmt("%.1f", f) + " Hz, +-" + fmt("%g", amplitude) + unit);
        // Settle three cycles (at least 0.1 s), record at least four
        // cycles and 0.3 s.
        const auto record = session->record(false, f, std::max(0.1, 3 / f), std::max(0.3, 4 / f) + 2 * period);
        FrequencyPoint p = analyse_sine(record, f);
        chirp.points.push_back(p);
        csv += response_csv(record, f);
      }
      session->end();
      write_file_atomically(chirp.csv, csv);
      chirp.bandwidth_hz = bandwidth_hz(chirp.points, chirp.bandwidth_above);
      for (const FrequencyPoint& p : chirp.points)
        report(prefix + "sine " + fmt("%.2f", p.frequency_hz) + " Hz: gain " + fmt("%.2f", p.gain_db) + " dB, phase " +
               fmt("%.1f", p.phase_deg) + " deg");
      report(prefix + "bandwidth (-3 dB): " + (chirp.bandwidth_above ? "above " : "") +
             fmt("%.1f", chirp.bandwidth_hz) + " Hz (" + chirp.csv + ")");
      (position ? result.position_chirp : result.chirp) = chirp;
    }
  } catch (const std::exception& e) {
    std::string off = switch_off_after_failure(c);
    if (session) off += session->end_after_failure();
    std::string why = e.what();
    if (abort_requested() && why.find("aborted") == std::string::npos)
      why = axis_name(a) + ": the response test was aborted (" + why + ")";
    throw std::runtime_error(why + off);
  }
  return result;
}

}  // namespace cnc::commission
