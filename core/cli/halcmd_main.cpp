// halcmd: inspects and changes the HAL of a running controller.
#include <unistd.h>

#include <cstdio>
#include <fstream>
#include <iostream>
#include <string>

#include "core/ipc/admin.hpp"
#include "core/ipc/segment.hpp"

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
               "  addf, delf, loadrt, loadusr, save, start, stop, source, echo.\n");
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
    if (!run_line(client, line, where)) {
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
      std::ifstream in(file);
      if (!in) {
        std::fprintf(stderr, "halcmd: cannot read %s\n", file.c_str());
        return 1;
      }
      return run_stream(client, in, file, keep_going, false);
    }
    if (i < argc) {
      std::string line;
      for (int k = i; k < argc; ++k) {
        std::string w = argv[k];
        if (w.find_first_of(" \t") != std::string::npos) w = "\"" + w + "\"";
        line += (k > i ? " " : "") + w;
      }
      return run_line(client, line, "") ? 0 : 1;
    }
    return run_stream(client, std::cin, "<stdin>", true, ::isatty(0) != 0);
  } catch (const std::exception& e) {
    std::fprintf(stderr, "halcmd: %s\n", e.what());
    return 1;
  }
}
