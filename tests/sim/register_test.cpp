// What the simulators add to a controller when a build registers them, and
// what a product registry lacks without them.
#include <gtest/gtest.h>

#include "core/hal/component.hpp"
#include "sim/register.hpp"

using namespace cnc;

TEST(SimRegister, RegistersEverySimulatorComponent) {
  hal::ComponentRegistry registry;
  for (const char* name : {"cia402_sim", "ethercat_sim", "sim_joint", "sim_toolchanger", "sim_part"}) {
    EXPECT_EQ(registry.find(name), nullptr) << name << " without the simulators";
  }
  sim::register_components(registry);
  for (const char* name : {"cia402_sim", "ethercat_sim", "sim_joint", "sim_toolchanger", "sim_part"}) {
    EXPECT_NE(registry.find(name), nullptr) << name;
  }
}
