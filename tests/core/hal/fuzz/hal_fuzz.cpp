// libFuzzer entry point: arbitrary bytes as halcmd input on a scratch HAL
// with the core and kinematics components and a small INI for [SECTION]KEY
// substitution. Each logical line (continuations joined) is tokenized and
// executed as a halcmd client's line, so `source` is refused; lines that
// would start programs or threads (loadusr, start) are tokenized but not
// run. Anything but HalError or ConfigError, a crash, a sanitizer report
// or a hang is a bug.
#include <cstddef>
#include <cstdint>
#include <string>
#include <string_view>

#include "core/hal/commands.hpp"
#include "core/ini/ini_file.hpp"
#include "core/util/error.hpp"
#include "core/util/messages.hpp"
#include "core/util/strings.hpp"
#include "kinematics/kinematics.hpp"

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, std::size_t size) {
  using namespace cnc;
  static const hal::ComponentRegistry* registry = [] {
    auto* r = new hal::ComponentRegistry;
    hal::register_core_components(*r);
    kin::register_kinematics_components(*r);
    return r;
  }();
  static const ini::IniFile ini = ini::IniFile::parse(
      "[KINS]\nKINEMATICS = trivkins coordinates=XYZ\nJOINTS = 3\n[EMCMOT]\nSERVO_PERIOD = 1000000\n[X]\nY = 2.5\n",
      "/nonexistent-cnc-fuzz/fuzz.ini");
  hal::Hal h;
  MessageQueue messages;
  hal::CommandInterpreter interp(h, *registry, &ini, &messages);
  int lines = 0;
  for (const NumberedLine& l : continued_lines(std::string_view(reinterpret_cast<const char*>(data), size))) {
    if (++lines > 256) break;
    try {
      const auto words = hal::tokenize_hal_line(interp.substitute(l.text));
      if (!words.empty() && (words[0] == "loadusr" || words[0] == "start")) continue;
      interp.execute(l.text, hal::CommandInterpreter::Origin::Client);
    } catch (const hal::HalError&) {
    } catch (const ConfigError&) {
    }
  }
  return 0;
}
