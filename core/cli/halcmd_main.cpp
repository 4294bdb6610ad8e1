// halcmd: inspects and changes the HAL of a running controller.
#include <unistd.h>

#include <cstdio>
#include <filesystem>
#include <iostream>
#include <string>
#include <vector>

#include "core/ipc/admin.hpp"
#include "core/ipc/segment.hpp"
#include "core/util/atomic_file.hpp"
#include "core/util/strings.hpp"

namespace {
void usage() {
  std::fprintf(stderr,
               "usage: halcmd [-i INSTANCE] [-k] [-f FILE.hal | COMMAND [ARGS...]]\n"
               "  With a command: runs it on the controller and prints the answer.\n"
               "  -f FILE: runs every line of a .hal file ('-' reads standard input).\n"
               "  -k: keep going after an error in a file.\n"
               "  Without either: reads commands interactively.\n"
               "  Commands: show [comp|pin|sig|param|funct|thread] [pattern], list, getp, setp,\n"
               "  gets, sets, ptype, stype, net, newsig, delsig, linkpp, linkps, linksp, unlinkp,\n"
               "  addf, delf, loadrt, loadusr, save, start, stop, source, echo, scope.\n"
               "  watch [-n SECONDS] [-c COUNT] NAME...: prints the pins', parameters' or signals'\n"
               "  values every SECONDS (0.5), COUNT times (until Ctrl-C), one line each time.\n");
}

// `watch`: halmeter's job on a terminal. One getp/gets request per name and
// line; the controller's values are read as halcmd reads them.
int watch(cnc::ipc::AdminClient& client, const std::vector<std::string>& args) {
  double interval = 0.5;
  long count = -1;
  std::vector<std::string> names;
  for (std::size_t k = 0; k < args.size(); ++k) {
    if ((args[k] == "-n" || args[k] == "-c") && k + 1 < args.size()) {
      const auto v = cnc::parse_double(args[k + 1]);
      if (!v || *v <= 0) {
        std::fprintf(stderr, "halcmd: watch %s %s: expected a positive number\n", args[k].c_str(), args[k + 1].c_str());
        return 1;
      }
      if (args[k] == "-n") interval = *v;
      else count = static_cast<long>(*v);
      ++k;
    } else {
      names.push_back(args[k]);
    }
  }
  if (names.empty()) {
    std::fprintf(stderr, "halcmd: usage: watch [-n SECONDS] [-c COUNT] NAME...\n");
    return 1;
  }
  for (long n = 0; count < 0 || n < count; ++n) {
    if (n > 0) ::usleep(static_cast<useconds_t>(interval * 1e6));
    std::string line;
    for (const auto& name : names) {
      cnc::ipc::AdminReply r = client.request("getp " + name);
      if (!r.ok) r = client.request("gets " + name);
      if (!r.ok) {
        std::fprintf(stderr, "halcmd: watch: %s\n", r.text.c_str());
        return 1;
      }
      line += (line.empty() ? "" : "  ") + name + "=" + std::string(cnc::trim(r.text));
    }
    std::printf("%s\n", line.c_str());
    std::fflush(stdout);
  }
  return 0;
}

// Returns false on error.
bool run_line(cnc::ipc::AdminClient& client, const std::string& line, const std::string& where) {
  const cnc::ipc::AdminReply r = client.request(line);
  if (r.ok) {
    std::fputs(r.text.c_str(), stdout);
    return true;
  }
  std::fprintf(stderr, "%s%s\n", where.c_str(), r.text.c_str());
  return false;
}

bool is_source(const std::string& line) { return line.compare(0, 7, "source ") == 0 || line.compare(0, 7, "source\t") == 0; }

// Runs a .hal file line by line: halcmd reads it itself, with its user's
// permissions, and sends the lines (the controller never reads a file for a
// client). `source FILE` lines inside are followed the same way.
int run_file(cnc::ipc::AdminClient& client, const std::filesystem::path& path, bool keep_going, int depth,
             const std::string& where) {
  if (depth >= 16) {
    std::fprintf(stderr, "%ssource %s: files nested deeper than 16 (a source loop?)\n", where.c_str(), path.c_str());
    return 1;
  }
  std::string text;
  try {
    text = cnc::read_file(path);
  } catch (const std::exception& e) {
    std::fprintf(stderr, "%s%s\n", where.c_str(), e.what());
    return 1;
  }
  int errors = 0;
  for (const cnc::NumberedLine& l : cnc::continued_lines(text)) {
    const std::string at = path.string() + ":" + std::to_string(l.line) + ": ";
    bool ok = true;
    if (is_source(l.text)) {
      std::filesystem::path next = cnc::trim(std::string_view(l.text).substr(7));
      if (next.is_relative()) next = path.parent_path() / next;
      ok = run_file(client, next, keep_going, depth + 1, at) == 0;
    } else {
      ok = run_line(client, l.text, at);
    }
    if (!ok) {
      ++errors;
      if (!keep_going) return 1;
    }
  }
  return errors == 0 ? 0 : 1;
}

int run_stream(cnc::ipc::AdminClient& client, std::istream& in, const std::string& name, bool keep_going,
               bool interactive) {
  std::string line;
  int line_no = 0;
  int errors = 0;
  if (interactive) std::fputs("halcmd: ", stdout);
  while (std::getline(in, line)) {
    ++line_no;
    const int first = line_no;
    while (!line.empty() && line.back() == '\\') {
      line.pop_back();
      std::string next;
      if (!std::getline(in, next)) break;
      ++line_no;
      line += " " + next;
    }
    if (line == "exit" || line == "quit") break;
    const std::string where = interactive ? "" : name + ":" + std::to_string(first) + ": ";
    const bool ok = is_source(line)
                        ? run_file(client, std::string(cnc::trim(std::string_view(line).substr(7))), keep_going, 0, where) == 0
                        : run_line(client, line, where);
    if (!ok) {
      ++errors;
      if (!keep_going && !interactive) return 1;
    }
    if (interactive) {
      std::fflush(stdout);
      std::fputs("halcmd: ", stdout);
    }
  }
  if (interactive) std::fputs("\n", stdout);
  return errors == 0 ? 0 : 1;
}
}  // namespace

int main(int argc, char** argv) {
  std::string instance = cnc::ipc::default_instance();
  std::string file;
  bool keep_going = false;
  int i = 1;
  for (; i < argc; ++i) {
    const std::string a = argv[i];
    if (a == "-i" && i + 1 < argc) instance = argv[++i];
    else if (a == "-f" && i + 1 < argc) file = argv[++i];
    else if (a == "-k") keep_going = true;
    else if (a == "-h" || a == "--help") { usage(); return 0; }
    else break;
  }
  try {
    cnc::ipc::AdminClient client(instance);
    if (!file.empty()) {
      if (file == "-") return run_stream(client, std::cin, "<stdin>", keep_going, false);
      return run_file(client, file, keep_going, 0, "halcmd: ");
    }
    if (i < argc) {
      std::string line;
      for (int k = i; k < argc; ++k) {
        std::string w = argv[k];
        if (w.find_first_of(" \t") != std::string::npos) w = "\"" + w + "\"";
        line += (k > i ? " " : "") + w;
      }
      if (std::string(argv[i]) == "watch") return watch(client, std::vector<std::string>(argv + i + 1, argv + argc));
      if (std::string(argv[i]) == "source") {
        if (argc - i != 2) {
          std::fprintf(stderr, "halcmd: usage: source <file.hal>\n");
          return 1;
        }
        return run_file(client, argv[i + 1], keep_going, 0, "");
      }
      return run_line(client, line, "") ? 0 : 1;
    }
    return run_stream(client, std::cin, "<stdin>", true, ::isatty(0) != 0);
  } catch (const std::exception& e) {
    std::fprintf(stderr, "halcmd: %s\n", e.what());
    return 1;
  }
}
