#include "core/hal/commands.hpp"
#include "core/hal/scope.hpp"

#include <fnmatch.h>
#include <signal.h>
#include <sys/stat.h>
#include <sys/wait.h>
#include <unistd.h>

#include <chrono>
#include <cinttypes>
#include <cstdio>
#include <cstdlib>
#include <sstream>
#include <thread>

#include "core/ini/ini_file.hpp"
#include "core/util/atomic_file.hpp"
#include "core/util/error.hpp"
#include "core/util/strings.hpp"

namespace cnc::hal {
namespace {

bool matches(const std::string& name, const std::string& pattern) {
  if (pattern.empty()) return true;
  if (pattern.find_first_of("*?[") != std::string::npos) return fnmatch(pattern.c_str(), name.c_str(), 0) == 0;
  return name.rfind(pattern, 0) == 0;  // a plain pattern is a prefix, as in halcmd
}

std::string pad_left(const std::string& s, std::size_t w) { return s.size() >= w ? s : std::string(w - s.size(), ' ') + s; }
std::string pad_right(const std::string& s, std::size_t w) { return s.size() >= w ? s : s + std::string(w - s.size(), ' '); }

void need(const std::vector<std::string>& w, std::size_t min, const char* usage) {
  if (w.size() < min) throw HalError(std::string("usage: ") + usage);
}

}  // namespace

RemoteComponent::RemoteComponent(Hal& hal, const std::string& name) : Component(hal, name) {}

void RemoteComponent::add_pin(const std::string& name, Type type, PinDir dir) {
  switch (type) {
    case Type::Bit: make_pin<bool>(name, dir); break;
    case Type::Float: make_pin<double>(name, dir); break;
    case Type::S32: make_pin<int32_t>(name, dir); break;
    case Type::U32: make_pin<uint32_t>(name, dir); break;
    case Type::S64: make_pin<int64_t>(name, dir); break;
    case Type::U64: make_pin<uint64_t>(name, dir); break;
  }
}

std::vector<std::string> tokenize_hal_line(std::string_view line) {
  std::vector<std::string> out;
  std::string cur;
  bool in_quotes = false, have = false;
  for (std::size_t i = 0; i < line.size(); ++i) {
    const char c = line[i];
    if (in_quotes) {
      if (c == '"') in_quotes = false;
      else cur += c;
      continue;
    }
    if (c == '"') { in_quotes = true; have = true; continue; }
    if (c == '#') break;
    if (c == ' ' || c == '\t' || c == '\r' || c == '\n') {
      if (have) { out.push_back(cur); cur.clear(); have = false; }
      continue;
    }
    cur += c;
    have = true;
  }
  if (in_quotes) throw HalError("unterminated quote");
  if (have) out.push_back(cur);
  return out;
}

CommandInterpreter::CommandInterpreter(Hal& hal, const ComponentRegistry& registry, const ini::IniFile* ini,
                                       MessageQueue* messages)
    : hal_(hal), registry_(registry), ini_(ini), messages_(messages) {}

CommandInterpreter::~CommandInterpreter() { stop_user_programs(); }

std::string CommandInterpreter::substitute(std::string_view line) const {
  std::string out;
  for (std::size_t i = 0; i < line.size();) {
    const char c = line[i];
    if (c == '#') {  // comments are not substituted
      out.append(line.substr(i));
      break;
    }
    if (c == '[') {
      const std::size_t close = line.find(']', i);
      if (close == std::string_view::npos) throw HalError("'[' without ']'");
      const std::string section(line.substr(i + 1, close - i - 1));
      std::size_t k = close + 1;
      std::string key;
      if (k < line.size() && line[k] == '(') {
        const std::size_t end = line.find(')', k);
        if (end == std::string_view::npos) throw HalError("[" + section + "](KEY without ')'");
        key = std::string(line.substr(k + 1, end - k - 1));
        k = end + 1;
      } else {
        while (k < line.size() && (std::isalnum(static_cast<unsigned char>(line[k])) || line[k] == '_')) key += line[k++];
      }
      if (key.empty()) throw HalError("[" + section + "] must be followed by a key name");
      if (!ini_) throw HalError("[" + section + "]" + key + ": no INI file was given");
      const auto v = ini_->find(section, key);
      if (!v) throw HalError("[" + section + "]" + key + " is not in " + ini_->path().string());
      out += *v;
      i = k;
      continue;
    }
    if (c == '$') {
      std::size_t k = i + 1;
      std::string var;
      if (k < line.size() && line[k] == '(') {
        const std::size_t end = line.find(')', k);
        if (end == std::string_view::npos) throw HalError("$(VAR without ')'");
        var = std::string(line.substr(k + 1, end - k - 1));
        k = end + 1;
      } else {
        while (k < line.size() && (std::isalnum(static_cast<unsigned char>(line[k])) || line[k] == '_')) var += line[k++];
      }
      if (var.empty()) throw HalError("'$' must be followed by an environment variable name");
      const char* v = std::getenv(var.c_str());
      if (!v) throw HalError("environment variable " + var + " is not set");
      out += v;
      i = k;
      continue;
    }
    out += c;
    ++i;
  }
  return out;
}

namespace {
constexpr std::size_t kMaxSourceDepth = 16;
}  // namespace

std::string CommandInterpreter::execute(std::string_view line, Origin origin) {
  std::lock_guard lock(mutex_);
  const auto words = tokenize_hal_line(substitute(line));
  if (words.empty()) return {};
  return dispatch(words, origin);
}

void CommandInterpreter::run_file(const std::filesystem::path& path) {
  std::string text;
  try {
    text = read_file(path);
  } catch (const FileError& e) {
    throw ConfigError(path.string(), 0, "cannot read HAL file: " + e.reason());
  }
  run_text(text, path.string());
}

void CommandInterpreter::run_text(std::string_view text, const std::string& name) {
  std::lock_guard lock(mutex_);
  file_stack_.emplace_back(name);
  for (const NumberedLine& l : continued_lines(text)) {
    const int line_no = l.line;
    const std::string& line = l.text;
    try {
      execute(line);
    } catch (const ConfigError&) {
      file_stack_.pop_back();
      throw;  // from a nested `source`: already names its file
    } catch (const std::exception& e) {
      file_stack_.pop_back();
      throw ConfigError(name, line_no, e.what());
    }
  }
  file_stack_.pop_back();
}

std::string CommandInterpreter::dispatch(const std::vector<std::string>& w, Origin origin) {
  const std::string& cmd = w[0];
  // "name = value" is setp.
  if (w.size() == 3 && w[1] == "=") {
    hal_.set_value(w[0], w[2]);
    return {};
  }
  if (cmd == "loadrt") return cmd_loadrt(w);
  if (cmd == "loadusr") return cmd_loadusr(w);
  if (cmd == "net") {
    need(w, 3, "net <signal> <pin> [<pin> ...] (arrows => <= <=> are optional)");
    std::vector<std::string> pins;
    for (std::size_t i = 2; i < w.size(); ++i) {
      if (w[i] != "=>" && w[i] != "<=" && w[i] != "<=>") pins.push_back(w[i]);
    }
    hal_.net(w[1], pins);
    return {};
  }
  if (cmd == "setp") {
    need(w, 3, "setp <pin|param> <value>");
    hal_.set_value(w[1], w[2]);
    return {};
  }
  if (cmd == "sets") {
    need(w, 3, "sets <signal> <value>");
    hal_.set_signal(w[1], w[2]);
    return {};
  }
  if (cmd == "getp") {
    need(w, 2, "getp <pin|param>");
    return hal_.get_value(w[1]) + "\n";
  }
  if (cmd == "gets") {
    need(w, 2, "gets <signal>");
    return hal_.get_signal(w[1]) + "\n";
  }
  if (cmd == "ptype") {
    need(w, 2, "ptype <pin|param>");
    return std::string(to_string(hal_.type_of_name(w[1]))) + "\n";
  }
  if (cmd == "stype") {
    need(w, 2, "stype <signal>");
    return std::string(to_string(hal_.signal_type(w[1]))) + "\n";
  }
  if (cmd == "newsig") {
    need(w, 3, "newsig <signal> <type>");
    const auto t = parse_type(w[2]);
    if (!t) throw HalError("newsig: type \"" + w[2] + "\": expected bit, float, s32, u32, s64 or u64");
    hal_.new_signal(w[1], *t);
    return {};
  }
  if (cmd == "delsig") {
    need(w, 2, "delsig <signal>");
    hal_.delete_signal(w[1]);
    return {};
  }
  if (cmd == "linkps") {
    need(w, 3, "linkps <pin> <signal>");
    hal_.link(w[1], w[w.size() - 1]);
    return {};
  }
  if (cmd == "linksp") {
    need(w, 3, "linksp <signal> <pin>");
    hal_.link(w[w.size() - 1], w[1]);
    return {};
  }
  if (cmd == "linkpp") {
    need(w, 3, "linkpp <pin> <pin>");
    hal_.link_pins(w[1], w[w.size() - 1]);
    return {};
  }
  if (cmd == "unlinkp") {
    need(w, 2, "unlinkp <pin>");
    hal_.unlink(w[1]);
    return {};
  }
  if (cmd == "addf") {
    need(w, 3, "addf <function> <thread> [position]");
    int pos = -1;
    if (w.size() > 3) {
      const auto p = parse_int(w[3]);
      if (!p || *p == 0) throw HalError("addf: position \"" + w[3] + "\": expected a non-zero integer");
      pos = static_cast<int>(*p);
    }
    hal_.add_function(w[1], w[2], pos);
    return {};
  }
  if (cmd == "delf") {
    need(w, 3, "delf <function> <thread>");
    hal_.remove_function(w[1], w[2]);
    return {};
  }
  if (cmd == "start") {
    hal_.start_threads();
    return {};
  }
  if (cmd == "stop") {
    hal_.stop_threads();
    return {};
  }
  if (cmd == "show") return cmd_show(w);
  if (cmd == "list") return cmd_list(w);
  if (cmd == "save") return cmd_save();
  if (cmd == "echo" || cmd == "print") {
    std::string out;
    for (std::size_t i = 1; i < w.size(); ++i) out += (i > 1 ? " " : "") + w[i];
    return out + "\n";
  }
  // Remote components: a client process (the HMI, a panel) owns pins in the
  // controller's HAL and reads/writes them over this channel.
  if (cmd == "scope") {
    auto* scope = hal_.find<Scope>("scope");
    if (!scope) throw HalError("scope: no scope loaded (loadrt scope [samples=N], addf scope.sample servo-thread)");
    return scope->command(std::vector<std::string>(w.begin() + 1, w.end()));
  }
  if (cmd == "newcomp") {
    need(w, 2, "newcomp <name>");
    if (auto why = check_name(w[1]); !why.empty()) throw HalError("newcomp: " + why);
    hal_.add_component(std::make_unique<RemoteComponent>(hal_, w[1]));
    return {};
  }
  if (cmd == "newpin") {
    need(w, 5, "newpin <component> <pin> bit|float|s32|u32|s64|u64 in|out|io");
    auto* rc = dynamic_cast<RemoteComponent*>(hal_.find_component(w[1]));
    if (!rc) throw HalError("newpin: \"" + w[1] + "\" is not a component made with newcomp");
    if (w[2].rfind(w[1] + ".", 0) != 0) throw HalError("newpin: pin names of " + w[1] + " start with \"" + w[1] + ".\"");
    const auto t = parse_type(w[3]);
    if (!t) throw HalError("newpin: type \"" + w[3] + "\": expected bit, float, s32, u32, s64 or u64");
    const std::string d = to_lower(w[4]);
    const PinDir dir = d == "in" ? PinDir::In : d == "out" ? PinDir::Out : d == "io" ? PinDir::IO : PinDir::In;
    if (d != "in" && d != "out" && d != "io") throw HalError("newpin: direction \"" + w[4] + "\": expected in, out or io");
    rc->add_pin(w[2], *t, dir);
    return {};
  }
  if (cmd == "setr") {
    need(w, 3, "setr <pin of a newcomp component> <value>");
    hal_.set_owned_pin(w[1], w[2], [](const Component* owner) { return dynamic_cast<const RemoteComponent*>(owner) != nullptr; });
    return {};
  }
  if (cmd == "source") {
    need(w, 2, "source <file.hal>");
    if (origin == Origin::Client) {
      throw HalError("source: the controller reads only its configuration's files; halcmd reads a file itself "
                     "(halcmd -f FILE, or source FILE typed to halcmd) and sends its lines");
    }
    std::filesystem::path p = w[1];
    if (p.is_relative() && !file_stack_.empty()) p = file_stack_.back().parent_path() / p;
    // A file that sources itself, directly or through others, would recurse
    // until the stack overflows.
    std::error_code ec;
    const auto canon = std::filesystem::weakly_canonical(p, ec);
    std::string chain;
    bool loop = false;
    for (const auto& f : file_stack_) {
      chain += f.filename().string() + " -> ";
      loop = loop || std::filesystem::weakly_canonical(f, ec) == canon;
    }
    if (loop) throw HalError("source " + p.string() + ": a source loop (" + chain + p.filename().string() + ")");
    if (file_stack_.size() >= kMaxSourceDepth) {
      throw HalError("source " + p.string() + ": files nested deeper than " + std::to_string(kMaxSourceDepth));
    }
    run_file(p);
    return {};
  }
  throw HalError("unknown command \"" + cmd + "\"");
}

std::string CommandInterpreter::cmd_loadrt(const std::vector<std::string>& w) {
  need(w, 2, "loadrt <component> [key=value ...]");
  // `loadrt [KINS]KINEMATICS` may expand to "trivkins coordinates=XYZ".
  const ComponentRegistry::Entry* e = registry_.find(w[1]);
  if (!e) {
    std::string known;
    for (const auto* entry : registry_.entries()) known += (known.empty() ? "" : ", ") + entry->name;
    throw HalError("loadrt: no component named \"" + w[1] + "\"; available: " + known);
  }
  std::vector<std::pair<std::string, std::string>> kv;
  for (std::size_t i = 2; i < w.size(); ++i) {
    const auto eq = w[i].find('=');
    if (eq == std::string::npos || eq == 0) throw HalError("loadrt " + w[1] + ": argument \"" + w[i] + "\": expected key=value");
    kv.emplace_back(w[i].substr(0, eq), w[i].substr(eq + 1));
  }
  ComponentContext ctx{hal_, ini_, messages_};
  try {
    auto comp = e->factory(ctx, LoadArgs(w[1], std::move(kv)));
    if (comp) hal_.add_component(std::move(comp));
  } catch (...) {
    // What the component made before it failed must not outlive it.
    hal_.remove_orphans();
    throw;
  }
  return {};
}

std::string CommandInterpreter::cmd_loadusr(const std::vector<std::string>& w) {
  need(w, 2, "loadusr [-w] <program> [args ...]");
  std::size_t i = 1;
  bool wait_exit = false;
  while (i < w.size() && w[i].size() > 1 && w[i][0] == '-') {
    if (w[i] == "-w") {
      wait_exit = true;
    } else if (w[i] == "-W" || w[i] == "-Wn" || w[i] == "-i") {
      throw HalError("loadusr " + w[i] +
                     ": waiting for a userspace HAL component is not supported; components run inside the "
                     "controller (loadrt), loadusr only starts programs");
    } else {
      throw HalError("loadusr: unknown option " + w[i]);
    }
    if (w[i] == "-Wn") ++i;
    ++i;
  }
  if (i >= w.size()) throw HalError("loadusr: no program given");
  const std::string program = loadusr_program(w[i]).string();
  std::vector<char*> argv;
  for (std::size_t k = i; k < w.size(); ++k) argv.push_back(const_cast<char*>(w[k].c_str()));
  argv.push_back(nullptr);
  const pid_t pid = ::fork();
  if (pid < 0) throw HalError("loadusr: fork failed");
  if (pid == 0) {
    // the program starts with no signal blocked (cncd blocks SIGINT and
    // SIGTERM in all its threads, and exec keeps the mask)
    sigset_t none;
    sigemptyset(&none);
    ::sigprocmask(SIG_SETMASK, &none, nullptr);
    ::execv(program.c_str(), argv.data());
    std::fprintf(stderr, "loadusr: cannot run %s\n", program.c_str());
    ::_exit(127);
  }
  if (wait_exit) {
    int status = 0;
    ::waitpid(pid, &status, 0);
    if (!WIFEXITED(status) || WEXITSTATUS(status) != 0) {
      throw HalError("loadusr -w " + w[i] + ": exited with status " + std::to_string(WEXITSTATUS(status)));
    }
  } else {
    children_.push_back(pid);
  }
  return {};
}

std::filesystem::path CommandInterpreter::loadusr_program(const std::string& name) const {
  namespace fs = std::filesystem;
  std::vector<fs::path> dirs;
  if (ini_) {
    if (const auto v = ini_->find("HAL", "LOADUSR_PATH")) {
      for (const auto& d : split(*v, ':', true)) dirs.push_back(ini_->resolve_path(d));
    }
    if (ini_->path().has_parent_path()) dirs.push_back(ini_->path().parent_path());
  }
  std::error_code ec;
  const fs::path self = fs::read_symlink("/proc/self/exe", ec);
  if (!ec) {
    dirs.push_back(self.parent_path());
#ifdef CNC_HELPERS_FROM_BIN
    // Installed (docs/install.md): the helper programs (the simulators'
    // processes) are in /usr/lib/<triplet>/cnc, beside /usr/bin's cncd.
    if (fs::is_directory(self.parent_path() / CNC_HELPERS_FROM_BIN, ec)) {
      dirs.push_back(self.parent_path() / CNC_HELPERS_FROM_BIN);
    }
#endif
  }
  std::string allowed;
  for (auto& d : dirs) {
    d = fs::weakly_canonical(d, ec);
    allowed += (allowed.empty() ? "" : ", ") + d.string();
  }
  fs::path candidate;
  if (name.find('/') != std::string::npos) {
    candidate = fs::weakly_canonical(name, ec);
  } else {
    for (const auto& d : dirs) {
      if (fs::exists(d / name, ec)) {
        candidate = fs::weakly_canonical(d / name, ec);
        break;
      }
    }
    if (candidate.empty()) {
      throw HalError("loadusr " + name + ": no such program in the allowed folders (" + allowed +
                     "; [HAL]LOADUSR_PATH adds folders)");
    }
  }
  bool inside = false;
  for (const auto& d : dirs) {
    const auto rel = candidate.lexically_relative(d);
    inside = inside || (!rel.empty() && *rel.begin() != "..");
  }
  if (!inside) {
    throw HalError("loadusr " + name + ": " + candidate.string() + " is outside the allowed folders (" + allowed +
                   "; [HAL]LOADUSR_PATH adds folders)");
  }
  struct stat st {};
  if (::stat(candidate.c_str(), &st) != 0 || !S_ISREG(st.st_mode) || ::access(candidate.c_str(), X_OK) != 0) {
    throw HalError("loadusr " + name + ": " + candidate.string() + " is not an executable file");
  }
  return candidate;
}

void CommandInterpreter::stop_user_programs() {
  std::lock_guard lock(mutex_);
  for (pid_t pid : children_) ::kill(pid, SIGTERM);
  for (pid_t pid : children_) {
    int status = 0;
    for (int i = 0; i < 100; ++i) {
      if (::waitpid(pid, &status, WNOHANG) != 0) goto reaped;
      std::this_thread::sleep_for(std::chrono::milliseconds(10));
    }
    ::kill(pid, SIGKILL);
    ::waitpid(pid, &status, 0);
  reaped:;
  }
  children_.clear();
}

std::string CommandInterpreter::cmd_show(const std::vector<std::string>& w) const {
  const std::string what = w.size() > 1 ? w[1] : "all";
  const std::string pattern = w.size() > 2 ? w[2] : "";
  std::ostringstream out;
  const bool all = what == "all";
  if (all || what == "comp") {
    out << "Loaded HAL Components:\n";
    for (const Component* c : hal_.components()) {
      if (matches(c->name(), pattern)) out << "    RT  " << c->name() << "\n";
    }
    out << "\n";
  }
  if (all || what == "pin") {
    out << "Component Pins:\n" << pad_right("Owner", 14) << "Type  Dir         Value  Name\n";
    for (const PinView& p : hal_.pins()) {
      if (!matches(p.name, pattern)) continue;
      out << pad_right(p.owner, 14) << pad_right(to_string(p.type), 6) << pad_right(to_string(p.dir), 5)
          << pad_left(format_value(p.type, p.value), 12) << "  " << p.name;
      if (!p.signal.empty()) {
        out << (p.dir == PinDir::In ? " <== " : p.dir == PinDir::Out ? " ==> " : " <=> ") << p.signal;
      }
      out << "\n";
    }
    out << "\n";
  }
  if (all || what == "param") {
    out << "Parameters:\n" << pad_right("Owner", 14) << "Type  Dir         Value  Name\n";
    for (const ParamView& p : hal_.params()) {
      if (!matches(p.name, pattern)) continue;
      out << pad_right(p.owner, 14) << pad_right(to_string(p.type), 6) << pad_right(to_string(p.dir), 5)
          << pad_left(format_value(p.type, p.value), 12) << "  " << p.name << "\n";
    }
    out << "\n";
  }
  if (all || what == "sig") {
    out << "Signals:\nType          Value  Name     (linked to)\n";
    for (const SignalView& s : hal_.signals()) {
      if (!matches(s.name, pattern)) continue;
      out << pad_right(to_string(s.type), 6) << pad_left(format_value(s.type, s.value), 12) << "  " << s.name << "\n";
      if (!s.writer.empty()) out << "                         <== " << s.writer << "\n";
      for (const auto& b : s.bidirs) out << "                         <=> " << b << "\n";
      for (const auto& r : s.readers) out << "                         ==> " << r << "\n";
    }
    out << "\n";
  }
  if (all || what == "funct") {
    out << "Exported Functions:\n" << pad_right("Owner", 14) << "FP   Users      Time(ns)   Max(ns)  Name\n";
    for (const FunctionView& f : hal_.functions()) {
      if (!matches(f.name, pattern)) continue;
      out << pad_right(f.owner, 14) << pad_right(f.uses_fp ? "YES" : "NO", 5) << pad_left(std::to_string(f.users), 5)
          << pad_left(std::to_string(f.time_ns), 14) << pad_left(std::to_string(f.tmax_ns), 10) << "  " << f.name
          << "\n";
    }
    out << "\n";
  }
  if (all || what == "thread") {
    out << "Realtime Threads:\n     Period  FP     Name               (     Time, Max-Time )\n";
    for (const ThreadView& t : hal_.thread_views()) {
      if (!matches(t.name, pattern)) continue;
      out << pad_left(std::to_string(t.period_ns), 11) << "  " << pad_right(t.uses_fp ? "YES" : "NO", 4)
          << pad_left(t.name, 20) << " ( " << pad_left(std::to_string(t.time_ns), 8) << ", "
          << pad_left(std::to_string(t.tmax_ns), 8) << " )" << (t.running ? "" : "  stopped") << "\n";
      int n = 1;
      for (const auto& f : t.functions) out << pad_left(std::to_string(n++), 19) << " " << f << "\n";
    }
    out << "\n";
  }
  if (!all && what != "comp" && what != "pin" && what != "param" && what != "sig" && what != "funct" &&
      what != "thread") {
    throw HalError("show: unknown item \"" + what + "\"; expected comp, pin, sig, param, funct or thread");
  }
  return out.str();
}

std::string CommandInterpreter::cmd_list(const std::vector<std::string>& w) const {
  need(w, 2, "list comp|pin|sig|param|funct|thread [pattern]");
  const std::string pattern = w.size() > 2 ? w[2] : "";
  std::vector<std::string> names;
  if (w[1] == "comp") for (const Component* c : hal_.components()) names.push_back(c->name());
  else if (w[1] == "pin") for (const auto& p : hal_.pins()) names.push_back(p.name);
  else if (w[1] == "sig") for (const auto& s : hal_.signals()) names.push_back(s.name);
  else if (w[1] == "param") for (const auto& p : hal_.params()) names.push_back(p.name);
  else if (w[1] == "funct") for (const auto& f : hal_.functions()) names.push_back(f.name);
  else if (w[1] == "thread") for (const auto& t : hal_.thread_views()) names.push_back(t.name);
  else throw HalError("list: unknown item \"" + w[1] + "\"; expected comp, pin, sig, param, funct or thread");
  std::string out;
  for (const auto& n : names) {
    if (matches(n, pattern)) out += (out.empty() ? "" : " ") + n;
  }
  return out + "\n";
}

std::string CommandInterpreter::cmd_save() const {
  std::ostringstream out;
  out << "# signals and links\n";
  for (const SignalView& s : hal_.signals()) {
    out << "net " << s.name;
    if (!s.writer.empty()) out << " <= " << s.writer;
    for (const auto& b : s.bidirs) out << " <=> " << b;
    for (const auto& r : s.readers) out << " => " << r;
    out << "\n";
    if (s.writer.empty()) out << "sets " << s.name << " " << format_value(s.type, s.value) << "\n";
  }
  out << "# parameters\n";
  for (const ParamView& p : hal_.params()) {
    if (p.dir == ParamDir::RW && !p.name.ends_with(".tmax")) {
      out << "setp " << p.name << " " << format_value(p.type, p.value) << "\n";
    }
  }
  out << "# unconnected input pins\n";
  for (const PinView& p : hal_.pins()) {
    if (p.dir == PinDir::In && p.signal.empty()) out << "setp " << p.name << " " << format_value(p.type, p.value) << "\n";
  }
  out << "# functions\n";
  for (const ThreadView& t : hal_.thread_views()) {
    for (const auto& f : t.functions) out << "addf " << f << " " << t.name << "\n";
  }
  return out.str();
}

}  // namespace cnc::hal
