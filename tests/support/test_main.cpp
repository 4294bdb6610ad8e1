#include <dlfcn.h>
#include <gtest/gtest.h>
#include <sys/wait.h>
#include <unistd.h>

#include <array>
#include <atomic>
#include <cstdio>
#include <cstdlib>
#include <fstream>
#include <random>

#include "tests/support/testing.hpp"

#if defined(__SANITIZE_ADDRESS__)
#define CNC_ALLOC_WRAPPERS 0
#elif defined(__has_feature)
#if __has_feature(address_sanitizer)
#define CNC_ALLOC_WRAPPERS 0
#endif
#endif
#ifndef CNC_ALLOC_WRAPPERS
#define CNC_ALLOC_WRAPPERS 1
#endif

namespace {
std::atomic<uint64_t> g_allocations{0};
std::atomic<bool> g_all_threads{false};
thread_local bool t_armed = false;

inline void note_allocation() noexcept {
  if (t_armed || g_all_threads.load(std::memory_order_relaxed)) g_allocations.fetch_add(1, std::memory_order_relaxed);
}
}  // namespace

#if CNC_ALLOC_WRAPPERS
extern "C" {
void* __libc_malloc(size_t);
void* __libc_calloc(size_t, size_t);
void* __libc_realloc(void*, size_t);
void* __libc_memalign(size_t, size_t);

void* malloc(size_t n) {
  note_allocation();
  return __libc_malloc(n);
}
void* calloc(size_t n, size_t m) {
  note_allocation();
  return __libc_calloc(n, m);
}
void* realloc(void* p, size_t n) {
  note_allocation();
  return __libc_realloc(p, n);
}
void* aligned_alloc(size_t a, size_t n) {
  note_allocation();
  return __libc_memalign(a, n);
}
int posix_memalign(void** out, size_t a, size_t n) {
  note_allocation();
  void* p = __libc_memalign(a, n);
  if (!p) return ENOMEM;
  *out = p;
  return 0;
}
}
#endif

namespace cnc::testing {

void AllocationCounter::arm_this_thread() noexcept { t_armed = true; }
void AllocationCounter::disarm_this_thread() noexcept { t_armed = false; }
void AllocationCounter::arm_all_threads() noexcept { g_all_threads.store(true); }
void AllocationCounter::disarm_all_threads() noexcept { g_all_threads.store(false); }
uint64_t AllocationCounter::count() noexcept { return g_allocations.load(); }
void AllocationCounter::reset() noexcept { g_allocations.store(0); }
bool AllocationCounter::available() noexcept { return CNC_ALLOC_WRAPPERS != 0; }

ScopedAllocationCheck::ScopedAllocationCheck() noexcept : start_(g_allocations.load()) { t_armed = true; }
ScopedAllocationCheck::~ScopedAllocationCheck() { t_armed = false; }
uint64_t ScopedAllocationCheck::allocations() const noexcept { return g_allocations.load() - start_; }

CommandOutput run_shell(const std::string& command) {
  CommandOutput out;
  FILE* p = ::popen((command + " 2>&1").c_str(), "r");
  if (!p) return out;
  std::array<char, 4096> buf;
  while (std::fgets(buf.data(), buf.size(), p)) out.text += buf.data();
  const int status = ::pclose(p);
  out.code = WIFEXITED(status) ? WEXITSTATUS(status) : -1;
  return out;
}

std::string unique_name(const std::string& prefix) {
  static std::atomic<int> counter{0};
  std::random_device rd;
  return prefix + "-" + std::to_string(::getpid()) + "-" + std::to_string(counter.fetch_add(1)) + "-" +
         std::to_string(rd() % 100000);
}

TempDir::TempDir() {
  const auto base = std::filesystem::path(CNC_BINARY_DIR) / "test-tmp";
  std::filesystem::create_directories(base);
  path_ = base / unique_name("t");
  std::filesystem::create_directories(path_);
}

TempDir::~TempDir() {
  std::error_code ec;
  std::filesystem::remove_all(path_, ec);
}

std::filesystem::path TempDir::write(const std::string& name, const std::string& content) const {
  const auto p = path_ / name;
  std::filesystem::create_directories(p.parent_path());
  std::ofstream(p, std::ios::binary) << content;
  return p;
}

}  // namespace cnc::testing

int main(int argc, char** argv) {
  ::testing::InitGoogleTest(&argc, argv);
  return RUN_ALL_TESTS();
}
