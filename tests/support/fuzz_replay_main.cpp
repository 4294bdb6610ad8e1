// The main() of every <name>_fuzz_replay program (cmake: cnc_fuzz_target):
// runs a fuzz target's LLVMFuzzerTestOneInput on each file named on the
// command line (folders are walked), and on fixed variants of each (cut
// short at seven places, sixteen single bytes replaced), so that ctest
// keeps every harness building and the seed and regression corpora
// passing without clang or libFuzzer. A crash, an uncaught exception or a
// sanitizer report (with CNC_SANITIZE or CNC_FUZZ) fails the test; the
// input is named on stderr before it runs.
//   <name>_fuzz_replay [--no-variants] FILE|FOLDER...
#include <algorithm>
#include <chrono>
#include <cstdint>
#include <cstdio>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <string>
#include <vector>

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, std::size_t size);

namespace {

std::vector<std::filesystem::path> inputs_of(const std::filesystem::path& p) {
  std::vector<std::filesystem::path> out;
  if (std::filesystem::is_directory(p)) {
    for (const auto& e : std::filesystem::recursive_directory_iterator(p)) {
      if (e.is_regular_file()) out.push_back(e.path());
    }
    std::sort(out.begin(), out.end());
  } else if (std::filesystem::is_regular_file(p)) {
    out.push_back(p);
  }
  return out;
}

std::string read_all(const std::filesystem::path& p) {
  std::ifstream in(p, std::ios::binary);
  return std::string(std::istreambuf_iterator<char>(in), std::istreambuf_iterator<char>());
}

void run(const std::string& s) { LLVMFuzzerTestOneInput(reinterpret_cast<const uint8_t*>(s.data()), s.size()); }

}  // namespace

int main(int argc, char** argv) {
  bool variants = true;
  std::vector<std::filesystem::path> files;
  for (int i = 1; i < argc; ++i) {
    if (std::strcmp(argv[i], "--no-variants") == 0) {
      variants = false;
      continue;
    }
    const auto found = inputs_of(argv[i]);
    if (found.empty() && !std::filesystem::is_directory(argv[i])) {
      std::fprintf(stderr, "fuzz replay: %s: no such file or folder\n", argv[i]);
      return 2;
    }
    files.insert(files.end(), found.begin(), found.end());
  }
  if (files.empty()) {
    std::fprintf(stderr, "usage: %s [--no-variants] FILE|FOLDER...\n", argv[0]);
    return 2;
  }
  // Bytes the parsers care about: ends of lines, comments, quotes, section
  // and tag brackets, signs and digits, NUL and a high byte.
  static const char kBytes[] = {'\0', '\n', '#', '"', '[', '<', '-', '9', '=', ',', ' ', '\xff', '$', ';', '.', 'x'};
  const auto t0 = std::chrono::steady_clock::now();
  long runs = 0;
  for (const auto& f : files) {
    std::fprintf(stderr, "fuzz replay: %s\n", f.c_str());
    const std::string s = read_all(f);
    run(s);
    ++runs;
    if (!variants || s.empty()) continue;
    for (int k = 1; k < 8; ++k) {
      run(s.substr(0, s.size() * static_cast<std::size_t>(k) / 8));
      ++runs;
    }
    for (std::size_t k = 0; k < 16; ++k) {
      std::string v = s;
      v[(k * 2654435761u + 7) % v.size()] = kBytes[k];
      run(v);
      ++runs;
    }
  }
  const double secs = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  std::printf("fuzz replay: %zu inputs, %ld runs, %.2f s, nothing found\n", files.size(), runs, secs);
  return 0;
}
