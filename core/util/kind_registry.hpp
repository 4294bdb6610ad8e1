// A process-wide table of named openers ("socketcan", "virtual", "sim", ...)
// that modules register at start-up and readers look up by name: how the
// CAN transports and the EtherCAT links let the simulators add kinds the
// product does not know (docs/architecture.md, "Simulators"). Thread-safe;
// not for the servo thread.
#pragma once

#include <mutex>
#include <string>
#include <vector>

namespace cnc {

template <class Opener>
class KindRegistry {
 public:
  // Adds `name`, or replaces its opener.
  void add(const std::string& name, Opener open) {
    std::lock_guard<std::mutex> lock(mutex_);
    for (Kind& k : kinds_) {
      if (k.name == name) {
        k.open = open;
        return;
      }
    }
    kinds_.push_back({name, open});
  }
  // The opener of `name` (empty when none), and in `known` ", name" for
  // every kind registered, for the error that lists them.
  Opener find(const std::string& name, std::string& known) const {
    std::lock_guard<std::mutex> lock(mutex_);
    Opener found{};
    for (const Kind& k : kinds_) {
      if (k.name == name) found = k.open;
      known += ", " + k.name;
    }
    return found;
  }

 private:
  struct Kind {
    std::string name;
    Opener open;
  };
  mutable std::mutex mutex_;
  std::vector<Kind> kinds_;
};

}  // namespace cnc
