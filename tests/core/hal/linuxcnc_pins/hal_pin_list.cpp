// hal_pin_list FILE.hal: runs a HAL file in an in-process HAL (no
// controller, no thread started) and prints every pin and parameter as
// `pin|param NAME TYPE DIR VALUE` and `funct NAME`, one a line: the project's side of the
// comparison with LinuxCNC's component interfaces (run.sh beside it).
#include <cstdio>
#include <exception>

#include "core/hal/commands.hpp"

int main(int argc, char** argv) {
  if (argc != 2) {
    std::fprintf(stderr, "usage: hal_pin_list FILE.hal\n");
    return 2;
  }
  try {
    cnc::hal::Hal hal;
    cnc::hal::ComponentRegistry registry;
    cnc::hal::register_core_components(registry);
    cnc::hal::CommandInterpreter interp{hal, registry, nullptr, nullptr};
    interp.run_file(argv[1]);
    for (const auto& p : hal.pins()) {
      std::printf("pin %s %s %s %s\n", p.name.c_str(), to_string(p.type), to_string(p.dir),
                  cnc::hal::format_value(p.type, p.value).c_str());
    }
    for (const auto& p : hal.params()) {
      std::printf("param %s %s %s %s\n", p.name.c_str(), to_string(p.type), to_string(p.dir),
                  cnc::hal::format_value(p.type, p.value).c_str());
    }
    for (const auto& f : hal.functions()) std::printf("funct %s\n", f.name.c_str());
  } catch (const std::exception& e) {
    std::fprintf(stderr, "hal_pin_list: %s\n", e.what());
    return 1;
  }
  return 0;
}
