// interp_bench: how fast the interpreter turns a long program into canonical
// calls, and how much memory it needs, beside LinuxCNC's stand-alone `rs274`
// on the same file. Prints figures; never asserts on timing.
//
// Usage: interp_bench [--lines N] [--runs R] [--program FILE] [--keep]
//   Without --program it writes a mixed G1/G2/G3 serpentine of N motion
//   lines (default 200000) to a temporary file. Each measurement runs in a
//   child process (fork) so that its peak resident memory (ru_maxrss) is its
//   own; the best of R runs (default 3) is reported, with CPU time (user +
//   system) beside wall time because shared machines are noisy.
#include <sys/resource.h>
#include <sys/time.h>
#include <sys/wait.h>
#include <fcntl.h>
#include <unistd.h>

#include <chrono>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <filesystem>
#include <string>
#include <vector>

#include "core/interp/interp.hpp"
#include "core/interp/rs274_run.hpp"
#include "core/interp/text_canon.hpp"

namespace {

struct Figures {
  double wall_s = 0;
  double cpu_s = 0;
  long maxrss_kb = 0;
  int status = 0;
};

// Runs `fn` in a child; the child exits with fn's return value.
template <class Fn>
Figures measure(Fn fn) {
  const auto t0 = std::chrono::steady_clock::now();
  const pid_t pid = fork();
  if (pid == 0) {
    std::_Exit(fn());
  }
  int status = 0;
  rusage ru{};
  wait4(pid, &status, 0, &ru);
  const auto t1 = std::chrono::steady_clock::now();
  Figures f;
  f.wall_s = std::chrono::duration<double>(t1 - t0).count();
  f.cpu_s = ru.ru_utime.tv_sec + ru.ru_utime.tv_usec * 1e-6 + ru.ru_stime.tv_sec + ru.ru_stime.tv_usec * 1e-6;
  f.maxrss_kb = ru.ru_maxrss;
  f.status = WIFEXITED(status) ? WEXITSTATUS(status) : -1;
  return f;
}

template <class Fn>
Figures best_of(int runs, Fn fn) {
  Figures best;
  for (int i = 0; i < runs; ++i) {
    const Figures f = measure(fn);
    if (i == 0 || f.cpu_s < best.cpu_s) best = f;
  }
  return best;
}

void write_program(const std::string& path, long lines) {
  std::FILE* f = std::fopen(path.c_str(), "w");
  if (f == nullptr) {
    std::perror(path.c_str());
    std::exit(2);
  }
  std::fprintf(f, "(interp_bench: %ld motion lines, G1/G2/G3 serpentine, 1 mm segments)\n", lines);
  std::fprintf(f, "G21 G90 G17 G40 G49 G80 G94\nG64 P0.0100\nG0 X0 Y0 Z1\nG1 Z0 F3000.0000\n");
  const long per_row = 200;
  double y = 0;
  for (long i = 0; i < lines; ++i) {
    const long col = i % per_row;
    const bool back = (i / per_row) % 2 == 1;
    const double x0 = back ? per_row - col : col;
    const double x1 = back ? x0 - 1 : x0 + 1;
    if (col == per_row - 1) {
      y += 1;
      std::fprintf(f, "G1 X%.4f Y%.4f\n", x1, y);
    } else if (i % 4 == 1) {
      std::fprintf(f, "G2 X%.4f Y%.4f I%.4f J0\n", x1, y, (x1 - x0) / 2);
    } else if (i % 4 == 3) {
      std::fprintf(f, "G3 X%.4f Y%.4f I%.4f J0\n", x1, y, (x1 - x0) / 2);
    } else {
      std::fprintf(f, "G1 X%.4f Y%.4f\n", x1, y);
    }
  }
  std::fprintf(f, "G0 Z1\nG0 X0 Y0\nM2\n");
  std::fclose(f);
}

long count_lines(const std::string& path) {
  std::FILE* f = std::fopen(path.c_str(), "r");
  if (f == nullptr) return 0;
  long n = 0;
  int c;
  while ((c = std::fgetc(f)) != EOF) n += c == '\n';
  std::fclose(f);
  return n;
}

void report(const char* what, const Figures& f, long lines) {
  std::printf("%-34s wall %7.3f s  cpu %7.3f s  %10.0f blocks/s (cpu)  peak %7ld kB  rc=%d\n", what, f.wall_s, f.cpu_s,
              f.cpu_s > 0 ? lines / f.cpu_s : 0.0, f.maxrss_kb, f.status);
}

bool on_path(const char* prog) {
  const char* path = std::getenv("PATH");
  if (path == nullptr) return false;
  std::string p(path);
  std::size_t start = 0;
  while (start <= p.size()) {
    const std::size_t end = p.find(':', start);
    const std::string dir = p.substr(start, end == std::string::npos ? std::string::npos : end - start);
    if (access((dir + "/" + prog).c_str(), X_OK) == 0) return true;
    if (end == std::string::npos) break;
    start = end + 1;
  }
  return false;
}

}  // namespace

int main(int argc, char** argv) {
  long lines = 200000;
  int runs = 3;
  std::string program;
  bool keep = false;
  for (int i = 1; i < argc; ++i) {
    const std::string a = argv[i];
    if (a == "--lines" && i + 1 < argc) {
      lines = std::atol(argv[++i]);
    } else if (a == "--runs" && i + 1 < argc) {
      runs = std::atoi(argv[++i]);
    } else if (a == "--program" && i + 1 < argc) {
      program = argv[++i];
    } else if (a == "--keep") {
      keep = true;
    } else {
      std::fprintf(stderr, "usage: interp_bench [--lines N] [--runs R] [--program FILE] [--keep]\n");
      return 2;
    }
  }
  bool generated = false;
  if (program.empty()) {
    program = (std::filesystem::temp_directory_path() / ("interp_bench_" + std::to_string(getpid()) + ".ngc")).string();
    write_program(program, lines);
    generated = true;
  }
  const long nlines = count_lines(program);
  std::printf("program %s: %ld lines\n", program.c_str(), nlines);

  using namespace cnc::interp;
  const Figures null_canon = best_of(runs, [&] {
    TextCanon canon(nullptr);
    Interpreter in(canon);
    in.init();
    in.open(program);
    try {
      in.run_to_end();
    } catch (const InterpError& e) {
      std::fprintf(stderr, "%s\n", e.what());
      return 1;
    }
    return 0;
  });
  report("cnc interpreter, no output", null_canon, nlines);

  const Figures text = best_of(runs, [&] {
    std::FILE* out = std::fopen("/dev/null", "w");
    Rs274Options o;
    o.program = program;
    std::string err;
    const bool ok = run_rs274(o, out, err);
    std::fclose(out);
    return ok ? 0 : 1;
  });
  report("cnc interpreter, rs274 text", text, nlines);

  if (on_path("rs274")) {
    const Figures lcnc = best_of(runs, [&] {
      const int devnull = open("/dev/null", O_WRONLY);
      dup2(devnull, 1);
      dup2(devnull, 2);
      execlp("rs274", "rs274", "-g", program.c_str(), static_cast<char*>(nullptr));
      return 127;
    });
    report("LinuxCNC rs274 -g, text", lcnc, nlines);
    if (text.cpu_s > 0 && text.wall_s > 0) {
      std::printf("speed-up (rs274 text output): %.1fx by cpu time, %.1fx by wall time; memory %.1fx less\n",
                  lcnc.cpu_s / text.cpu_s, lcnc.wall_s / text.wall_s,
                  text.maxrss_kb > 0 ? static_cast<double>(lcnc.maxrss_kb) / text.maxrss_kb : 0.0);
    }
  } else {
    std::printf("LinuxCNC rs274 not installed (apt-get install linuxcnc-uspace): no comparison\n");
  }
  if (generated && !keep) std::filesystem::remove(program);
  return 0;
}
