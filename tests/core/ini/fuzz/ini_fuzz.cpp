// libFuzzer entry point: arbitrary bytes as an INI file. Parsed, every
// entry read through each typed getter and path resolution, then the
// motion configuration (the largest reader of INI values) loaded from it.
// Anything but ConfigError, a crash, a sanitizer report or a hang is a bug.
#include <algorithm>
#include <cstddef>
#include <cstdint>
#include <string>

#include "core/ini/ini_file.hpp"
#include "core/motion/config.hpp"
#include "core/util/error.hpp"

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, std::size_t size) {
  using cnc::ini::IniFile;
  // A folder that does not exist: relative #INCLUDEs find nothing.
  const std::string name = "/nonexistent-cnc-fuzz/fuzz.ini";
  IniFile ini;
  try {
    ini = IniFile::parse(std::string_view(reinterpret_cast<const char*>(data), size), name);
  } catch (const cnc::ConfigError&) {
    return 0;
  }
  for (const std::string& section : ini.sections()) {
    for (const cnc::ini::Entry* e : ini.section_entries(section)) {
      (void)ini.get_string(e->section, e->key, "");
      (void)ini.find_all(e->section, e->key);
      (void)ini.resolve_path(e->value);
      try {
        (void)ini.get_double(e->section, e->key, 0, {-1e9, 1e9});
      } catch (const cnc::ConfigError&) {
      }
      try {
        (void)ini.get_int(e->section, e->key, 0, {0, 100});
      } catch (const cnc::ConfigError&) {
      }
      try {
        (void)ini.get_bool(e->section, e->key, false);
      } catch (const cnc::ConfigError&) {
      }
    }
  }
  try {
    const int joints = static_cast<int>(ini.get_int("KINS", "JOINTS", 3, {1, cnc::kMaxJoints}));
    (void)cnc::motion::load_motion_config(ini, joints);
  } catch (const cnc::ConfigError&) {
  }
  return 0;
}
