#include "core/daemon/controller.hpp"

#include <signal.h>
#include <unistd.h>

#include <algorithm>
#include <cstdio>
#include <ctime>
#include <thread>

#include "core/daemon/ini_check.hpp"
#include "core/ipc/command_check.hpp"
#include "core/rt/periodic_task.hpp"
#include "core/util/error.hpp"
#ifdef CNC_HAVE_MOTION
#include "core/motion/motion_component.hpp"
#endif
#ifdef CNC_HAVE_IO
#include "core/io/io_controller.hpp"
#endif
#ifdef CNC_HAVE_TASK
#include "core/task/task_controller.hpp"
#endif
#include "core/util/strings.hpp"
#include "core/util/time.hpp"

namespace cnc::daemon {
namespace {

void log_line(const char* kind, const std::string& source, const std::string& text) {
  const int64_t now = realtime_ns();
  const time_t secs = static_cast<time_t>(now / 1'000'000'000);
  tm local{};
  localtime_r(&secs, &local);
  char stamp[32];
  std::strftime(stamp, sizeof stamp, "%H:%M:%S", &local);
  std::fprintf(stderr, "%s.%03d cncd %s [%s] %s\n", stamp, static_cast<int>((now / 1'000'000) % 1000), kind,
               source.c_str(), text.c_str());
}

}  // namespace

Controller::Controller(const Options& options) : options_(options), status_(std::make_unique<ipc::Status>()) {
  started_ns_ = realtime_ns();
  ini_ = ini::IniFile::load(options.ini_file);
  check_section_names(ini_);
  // Every lookup from here to the end of start-up is recorded: the keys
  // nobody asked for are reported then (check_ini_keys).
  ini_.record_reads(true);
  if (ini_.find_all_entries("HAL", "HALFILE").empty() && ini_.find_all_entries("HAL", "HALCMD").empty()) {
    throw ConfigError(ini_.path().string(), 0,
                      "no [HAL]HALFILE or [HAL]HALCMD: nothing to run (is this a machine's INI file?)");
  }
  // Everything the daemon itself uses is read here, at start-up, so that
  // the key check (check_ini_keys) sees it read.
  if (const auto file = ini_.find("HAL", "SHUTDOWN")) shutdown_hal_ = ini_.resolve_path(*file);
  machine_ = ini_.get_string("EMC", "MACHINE", "");
  const double cycle_s = ini_.get_double("TASK", "CYCLE_TIME", 0.001, {0.0001, 1.0});
  cycle_ns_ = static_cast<int64_t>(cycle_s * 1e9);
  try {
    access_ = ipc::AccessPolicy::for_current_user(ini_.get_string("EMC", "OPERATOR_GROUP", ""));
  } catch (const std::runtime_error& e) {
    const ini::Entry* entry = ini_.find_all_entries("EMC", "OPERATOR_GROUP").front();
    throw ConfigError(entry->file, entry->line, std::string("[EMC]OPERATOR_GROUP: ") + e.what());
  }
  // A check touches no instance: it runs beside a live controller.
  if (!options.check_only) server_ = std::make_unique<ipc::Server>(options.instance, access_);

  const rt::RealtimeCapabilities& caps = rt::prepare_process();
  if (!caps.note.empty()) {
    log_line("warning", "rt", caps.note);
    messages_.post(MessageKind::Text, "rt", caps.note);
  }

  register_all_components(registry_);
  for (Registrar r : options.extra_components) r(registry_);
  interp_ = std::make_unique<hal::CommandInterpreter>(hal_, registry_, &ini_, &messages_);
  try {
#ifdef CNC_HAVE_IO
    // The I/O controller exists before the HAL files run so that they can
    // net its pins (LinuxCNC starts iocontrol the same way, from [EMCIO]).
    if (ini_.has_section("EMCIO")) {
      hal_.add_component(std::make_unique<io::IoController>(hal_, io::IoConfig::from_ini(ini_), &messages_));
    }
#endif
    for (const ini::Entry* e : ini_.find_all_entries("HAL", "HALFILE")) {
      std::string file = e->value;
      if (file.rfind("LIB:", 0) == 0) file = file.substr(4);
      const auto path = ini_.resolve_path(file);
      if (options_.verbose) log_line("info", "hal", "running " + path.string());
      interp_->run_file(path);
    }
    for (const ini::Entry* e : ini_.find_all_entries("HAL", "HALCMD")) {
      try {
        interp_->execute(e->value);
      } catch (const std::exception& ex) {
        throw ConfigError(e->file, e->line, "[HAL]HALCMD: " + std::string(ex.what()));
      }
    }
    // [HAL]HALUI = halui: LinuxCNC's launcher starts halui after the HAL
    // files (its pins are netted in POSTGUI_HALFILEs); here it is the
    // halui component, loaded at the same point.
    if (const ini::Entry* e = ini_.find_entry("HAL", "HALUI")) {
      if (e->value != "halui") {
        throw ConfigError(e->file, e->line, "[HAL]HALUI = " + e->value + ": only halui (this controller's component) can be started");
      }
      if (hal_.find_component("halui")) {
        throw ConfigError(e->file, e->line, "[HAL]HALUI = halui, and a HAL file or [HAL]HALCMD loads halui too: keep one of them");
      }
      interp_->execute("loadrt halui");
    }
    for (hal::Component* c : hal_.components()) c->on_ready();
  } catch (...) {
    hal_.stop_threads();
    interp_->stop_user_programs();
    throw;
  }
  for (hal::Component* c : hal_.components()) {
    if (auto* s = dynamic_cast<ipc::ControllerService*>(c)) services_.push_back(s);
  }
#ifdef CNC_HAVE_TASK
  // The task controller joins when the machine has motion and I/O.
  {
    auto* motion = hal_.find<motion::MotionComponent>("motmod");
    auto* io = hal_.find<io::IoController>("iocontrol");
    if (motion && io) {
      try {
        task_ = std::make_unique<task::TaskController>(ini_, hal_, *motion, *io, messages_);
      } catch (...) {
        hal_.stop_threads();
        interp_->stop_user_programs();
        throw;
      }
      services_.push_back(task_.get());
    } else if (motion) {
      log_line("warning", "cncd", "no [EMCIO] section: no I/O controller, so no task controller (programs and MDI)");
    }
  }
#endif
  std::stable_sort(services_.begin(), services_.end(),
                   [](const ipc::ControllerService* a, const ipc::ControllerService* b) {
                     return a->service_order() < b->service_order();
                   });
  try {
    check_ini_keys();
  } catch (...) {
    hal_.stop_threads();
    interp_->stop_user_programs();
    throw;
  }
  if (options.check_only) return;
  wire_estop();
  admin_ = std::make_unique<ipc::AdminServer>(
      options.instance, [this](const std::string& line) { return admin_request(line); }, access_);
  hal_.start_threads();
  threads_started_ = true;
  publish_status();
  server_->set_ready(true);
  log_line("info", "cncd",
           "instance \"" + options.instance + "\" running " + ini_.path().string() + " (pid " +
               std::to_string(::getpid()) + ")");
}

Controller::~Controller() { shutdown(); }

void Controller::check_ini_keys() {
  const std::string mode = to_upper(ini_.get_string("EMC", "UNKNOWN_KEYS", "WARN"));
  if (mode != "WARN" && mode != "ERROR") {
    ini_.fail(ini_.find_entry("EMC", "UNKNOWN_KEYS"), "expected WARN or ERROR, got \"" + mode + "\"");
  }
  const bool strict = options_.strict || mode == "ERROR";
  const std::vector<IniIssue> issues = find_unread_keys(ini_);
  // Later lookups (halcmd's [SECTION]KEY from the admin thread, the task
  // at run time) are not recorded: the records are not synchronised.
  ini_.record_reads(false);
  std::vector<const IniIssue*> mistakes;
  std::string ignored;
  int ignored_count = 0;
  for (const IniIssue& i : issues) {
    if (i.is_mistake()) {
      mistakes.push_back(&i);
      continue;
    }
    // LinuxCNC keys without effect here: one line of information.
    if (++ignored_count <= 6) ignored += (ignored.empty() ? "" : ", ") + i.text.substr(0, i.text.find(':'));
  }
  if (ignored_count > 6) ignored += " and " + std::to_string(ignored_count - 6) + " more";
  if (!ignored.empty()) {
    const std::string text = "LinuxCNC keys this controller does not use (docs/configuration.md): " + ignored;
    messages_.post(MessageKind::Text, "ini", text);
  }
  // Warnings go to the message channel (and from there to the log); errors
  // to the log at once, since the start-up ends here.
  for (const IniIssue* i : mistakes) {
    if (strict) log_line("error", "ini", i->where_and_what());
    else messages_.post(MessageKind::Text, "ini", i->where_and_what());
  }
  if (strict && !mistakes.empty()) {
    const IniIssue& first = *mistakes.front();
    throw ConfigError(first.file, first.line,
                      first.text + (mistakes.size() > 1 ? " (and " + std::to_string(mistakes.size() - 1) +
                                                              " more, listed above)"
                                                        : std::string()) +
                          "; unknown and unused keys are errors with " +
                          (options_.strict ? "cncd --strict" : "[EMC]UNKNOWN_KEYS = ERROR"));
  }
}

// E-stop is acted on in the servo thread for every configuration, without a
// HAL file: motion reads the segment's E-stop requests and the E-stop chain
// (docs/architecture.md, "E-stop").
void Controller::wire_estop() {
#ifdef CNC_HAVE_MOTION
  auto* motion = hal_.find<motion::MotionComponent>("motmod");
  if (!motion) return;
  hal::BitPin chain;
#ifdef CNC_HAVE_IO
  if (auto* io = hal_.find<io::IoController>("iocontrol")) chain = io->estop_chain_pin();
#endif
  motion->set_estop_inputs(&server_->segment().header.estop, chain);
#endif
}

bool Controller::inject(const ipc::Command& cmd) {
  const auto words = split_blanks(cmd.text.view());
  if (words.empty() || !iequals(words[0], "task")) return false;
  bool simulated = false;
  for (const ipc::ControllerService* s : services_) simulated = simulated || s->is_simulator();
  if (!simulated) {
    report(cmd, ipc::CommandState::Rejected,
           "\"" + std::string(cmd.text.view()) + "\": fault injection works on simulated machines only");
    return true;
  }
  const auto seconds = words.size() == 3 && iequals(words[1], "stall") ? parse_double(words[2]) : std::nullopt;
  if (!seconds || !(*seconds > 0 && *seconds <= 60)) {
    report(cmd, ipc::CommandState::Rejected,
           "\"" + std::string(cmd.text.view()) + "\": expected \"task stall SECONDS\" (0 to 60)");
    return true;
  }
  // Answered first: the stall is what the client wants to observe.
  report(cmd, ipc::CommandState::Done, {});
  stall_ns_ = static_cast<int64_t>(*seconds * 1e9);
  messages_.post(MessageKind::Text, "cncd", "fault injection: the task cycle stalls for " + format_double(*seconds) + " s");
  return true;
}

ipc::AdminReply Controller::admin_request(const std::string& line) {
  try {
    return {true, interp_->execute(line, hal::CommandInterpreter::Origin::Client)};
  } catch (const std::exception& e) {
    return {false, e.what()};
  }
}

void Controller::report(const ipc::Command& cmd, ipc::CommandState state, std::string_view reason) {
  server_->report(cmd, state, reason);
  if (state == ipc::CommandState::Rejected && options_.verbose) {
    log_line("info", "command", std::string(ipc::to_string(cmd.type)) + " rejected: " + std::string(reason));
  }
}

void Controller::dispatch(const ipc::Command& cmd) {
  using ipc::CommandType;
  if (const std::string why = ipc::check_arguments(cmd); !why.empty()) {
    report(cmd, ipc::CommandState::Rejected, std::string(ipc::to_string(cmd.type)) + ": " + why);
    return;
  }
  switch (cmd.type) {
    case CommandType::Ping:
      report(cmd, ipc::CommandState::Done, {});
      return;
    case CommandType::Shutdown:
      report(cmd, ipc::CommandState::Done, {});
      stop();
      return;
    case CommandType::OperatorError:
    case CommandType::OperatorText:
    case CommandType::OperatorDisplay: {
      const MessageKind kind = cmd.type == CommandType::OperatorError  ? MessageKind::Error
                               : cmd.type == CommandType::OperatorText ? MessageKind::Text
                                                                       : MessageKind::Display;
      messages_.post(kind, "operator", cmd.text.view());
      report(cmd, ipc::CommandState::Done, {});
      return;
    }
    case CommandType::AlarmAcknowledge: {
      const auto id = static_cast<uint32_t>(cmd.i[0]);
      if (alarms_.acknowledge(id, realtime_ns()) == 0 && id != 0) {
        report(cmd, ipc::CommandState::Rejected,
               "no active alarm " + std::to_string(id) + " (unknown or already acknowledged; `cnc alarms` lists them)");
        return;
      }
      report(cmd, ipc::CommandState::Done, {});
      return;
    }
    case CommandType::SimInject:
      if (inject(cmd)) return;
      break;
    default:
      break;
  }
  for (ipc::ControllerService* s : services_) {
    if (s->handle_command(cmd, *this)) return;
  }
  report(cmd, ipc::CommandState::Rejected,
         std::string("no part of this controller handles '") + ipc::to_string(cmd.type) +
             "' (is the component that does, e.g. the task or motion controller, loaded in the HAL files?)");
}

void Controller::drain_messages() {
  // The threads' overrun reports, formatted here, not in the thread. They
  // are errors where SCHED_FIFO promised the timing; without it (the
  // operator was told at start-up) they inform.
  hal::OverrunEvent ev;
  for (hal::Thread* t : hal_.threads()) {
    while (t->poll_overrun_event(ev)) {
      const bool error = t->task().uses_fifo() && ev.kind != hal::OverrunEvent::Kind::Ended;
      messages_.post(error ? MessageKind::Error : MessageKind::Text, t->name(), hal::describe(ev));
    }
  }
  Message m;
  while (messages_.pop(m)) {
    alarms_.post(m);
    if (server_) server_->post(m);
    log_line(to_string(m.kind), m.source.c_str(), m.text.c_str());
  }
}

void Controller::publish_status() {
  ipc::Status& s = *status_;
  s.health.heartbeat = ++heartbeat_;
  s.health.time_ns = realtime_ns();
  s.health.started_ns = started_ns_;
  s.health.pid = ::getpid();
  const rt::RealtimeCapabilities& caps = rt::prepare_process();
  s.health.realtime_memory_locked = caps.memory_locked;
  s.health.realtime_note.assign(caps.note);
  s.health.ini_file.assign(ini_.path().string());
  s.health.machine.assign(machine_);
  s.health.messages_dropped = messages_.dropped();
  s.health.task_cycle_ns = cycle_ns_;
  s.health.shutting_down = stop_requested_.load();
  int i = 0;
  bool fifo = false;
  for (hal::Thread* t : hal_.threads()) {
    if (i >= ipc::kMaxThreads) break;
    const rt::TimingSnapshot snap = t->task().stats().snapshot();
    ipc::ThreadStatus& ts = s.threads[i++];
    ts.name.assign(t->name());
    ts.fifo = t->task().uses_fifo();
    fifo = fifo || ts.fifo;
    ts.period_ns = t->period_ns();
    ts.cycles = snap.cycles;
    ts.overruns = snap.overruns;
    ts.missed_cycles = snap.missed_cycles;
    ts.overrun_streak = snap.overrun_streak;
    ts.longest_streak = snap.longest_streak;
    ts.longest_gap = snap.longest_gap;
    ts.late_wakes = t->late_wakes();
    const hal::Function* worst = t->worst_function();
    ts.overrun_function.assign(worst ? std::string_view(worst->name) : std::string_view());
    ts.overrun_function_count = worst ? hal::Thread::overruns_of(*worst) : 0;
    ts.overrun_function_max_ns = worst ? worst->overrun_max_ns.load(std::memory_order_relaxed) : 0;
    ts.latency_min_ns = snap.latency_min_ns;
    ts.latency_p50_ns = snap.latency_percentile_ns(0.5);
    ts.latency_p99_ns = snap.latency_percentile_ns(0.99);
    ts.latency_p999_ns = snap.latency_percentile_ns(0.999);
    ts.latency_max_ns = snap.latency_max_ns;
    ts.period_min_ns = snap.actual_period_min_ns;
    ts.period_max_ns = snap.actual_period_max_ns;
    ts.exec_last_ns = snap.exec_last_ns;
    ts.exec_max_ns = snap.exec_max_ns;
    ts.product_exec_last_ns = t->product_exec_last_ns();
    ts.product_exec_max_ns = t->product_exec_max_ns();
    ts.sim_exec_last_ns = t->simulation_exec_last_ns();
    ts.sim_exec_max_ns = t->simulation_exec_max_ns();
  }
  for (; i < ipc::kMaxThreads; ++i) s.threads[i] = ipc::ThreadStatus{};
  s.health.realtime_fifo = fifo;
  for (ipc::SimulatorStatus& sim : s.simulators) sim = ipc::SimulatorStatus{};  // simulators fill their own
  s.alarms = alarms_.status();
  for (ipc::ControllerService* svc : services_) svc->contribute_status(s);
  server_->publish(s);
}

void Controller::cycle() {
  ipc::Command cmd;
  for (int n = 0; n < 64 && server_->poll_command(cmd); ++n) dispatch(cmd);
  const int64_t now = monotonic_ns();
  for (ipc::ControllerService* s : services_) s->update(now);
  drain_messages();
  publish_status();
  if (stall_ns_ > 0) {
    std::this_thread::sleep_for(std::chrono::nanoseconds(stall_ns_));
    stall_ns_ = 0;
  }
}

void Controller::run(bool handle_signals) {
  sigset_t set;
  sigemptyset(&set);
  sigaddset(&set, SIGINT);
  sigaddset(&set, SIGTERM);
  if (handle_signals) pthread_sigmask(SIG_BLOCK, &set, nullptr);
  int64_t next = monotonic_ns();
  while (!stop_requested_.load()) {
    cycle();
    next += cycle_ns_;
    const int64_t wait = next - monotonic_ns();
    if (wait <= 0) {
      next = monotonic_ns();
      continue;
    }
    if (handle_signals) {
      const timespec ts = to_timespec(wait);
      siginfo_t info{};
      const int sig = sigtimedwait(&set, &info, &ts);
      if (sig == SIGINT || sig == SIGTERM) {
        log_line("info", "cncd", std::string("received ") + (sig == SIGINT ? "SIGINT" : "SIGTERM") + ", shutting down");
        stop();
      }
    } else {
      std::this_thread::sleep_for(std::chrono::nanoseconds(wait));
    }
  }
  shutdown();
}

void Controller::shutdown() {
  if (shut_down_) return;
  shut_down_ = true;
  stop_requested_.store(true);
  if (server_) server_->set_ready(false);
  // Services first (the task ends a running program and goes to E-stop,
  // saying why), then outputs to a safe state while the servo thread runs.
  for (ipc::ControllerService* s : services_) s->on_controller_shutdown();
  for (hal::Component* c : hal_.components()) c->on_shutdown();
  const int64_t deadline = monotonic_ns() + 2'000'000'000;
  // After a check (threads never started) there are no outputs to wait for.
  while (threads_started_) {
    cycle();
    bool safe = true;
    for (const ipc::ControllerService* s : services_) safe = safe && s->is_safe_to_stop();
    if (safe) break;
    if (monotonic_ns() > deadline) {
      log_line("error", "cncd", "outputs not confirmed safe within 2 s; stopping anyway");
      break;
    }
    std::this_thread::sleep_for(std::chrono::nanoseconds(cycle_ns_));
  }
  if (!shutdown_hal_.empty() && threads_started_) {
    try {
      interp_->run_file(shutdown_hal_);
    } catch (const std::exception& e) {
      log_line("error", "hal", std::string("[HAL]SHUTDOWN: ") + e.what());
    }
  }
  drain_messages();
  admin_.reset();
  hal_.stop_threads();
  interp_->stop_user_programs();
  services_.clear();
  task_.reset();
  hal_.clear();
  if (threads_started_) log_line("info", "cncd", "stopped");
  server_.reset();  // removes the segment: clients now see "not running"
}

}  // namespace cnc::daemon
