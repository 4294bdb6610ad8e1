// forward and inverse of every module, loaded as the controller loads them
// (geometry on HAL pins), allocate nothing: many calls with the allocation
// counter armed.
#include <gtest/gtest.h>

#include "core/hal/commands.hpp"
#include "core/hal/hal.hpp"
#include "kinematics/kinematics.hpp"
#include "tests/support/testing.hpp"

using namespace cnc;
using namespace cnc::kin;

namespace {

struct Case {
  const char* load;
  std::vector<const char*> setp;
};

class Allocation : public ::testing::TestWithParam<Case> {};

}  // namespace

TEST_P(Allocation, ForwardAndInverseAllocateNothing) {
  if (!cnc::testing::AllocationCounter::available()) GTEST_SKIP() << "allocation counter not available";
  hal::Hal hal;
  hal::ComponentRegistry registry;
  register_kinematics_components(registry);
  hal::CommandInterpreter interp(hal, registry, nullptr, nullptr);
  interp.execute(std::string("loadrt ") + GetParam().load);
  for (const char* s : GetParam().setp) interp.execute(std::string("setp ") + s);
  KinematicsComponent* comp = nullptr;
  for (hal::Component* c : hal.components()) {
    if (auto* k = dynamic_cast<KinematicsComponent*>(c)) comp = k;
  }
  ASSERT_NE(comp, nullptr);
  Kinematics& k = comp->kinematics();

  double joints[kMaxJoints] = {12, -25, 40, 15, 35, -20, 1, 2, 3};
  double hint[kMaxJoints];
  std::copy(joints, joints + kMaxJoints, hint);
  int ok = 0;
  uint64_t allocations = 0;
  {
    cnc::testing::ScopedAllocationCheck check;
    for (int i = 0; i < 2000; ++i) {
      joints[0] = 12 + 0.01 * i;  // a moving machine
      Pose p;
      if (k.forward(joints, p) != KinResult::Ok) continue;
      double out[kMaxJoints];
      if (k.inverse(p, hint, out) == KinResult::Ok) ++ok;
      std::copy(out, out + kMaxJoints, hint);
    }
    // Switching (while stopped) does not allocate either.
    k.switch_to(1);
    k.switch_to(0);
    allocations = check.allocations();
  }
  EXPECT_EQ(allocations, 0u);
  EXPECT_EQ(ok, 2000) << "every call computed something";
}

INSTANTIATE_TEST_SUITE_P(
    EveryModule, Allocation,
    ::testing::Values(Case{"trivkins coordinates=XYYZABCUV kinstype=B", {}},
                      Case{"matrixkins coordinates=XYZ c-xy=0.001 c-yx=-0.0005", {}},
                      Case{"xyzac-trt-kins z-rot-point=-100 y-offset=2 tool-offset=50", {}},
                      Case{"xyzbc-trt-kins coordinates=XYYZBC x-offset=3", {"xyzbc-trt-kins.tool-offset 40"}},
                      Case{"headtable-kins pivot-length=150 tool-offset=30", {}},
                      Case{"scarakins", {}},
                      Case{"genserkins a-1=85 a-2=380 a-3=100 d-0=350 d-3=425 d-5=100",
                           {"genserkins.alpha-1 -1.5707963267948966", "genserkins.alpha-3 -1.5707963267948966",
                            "genserkins.alpha-4 1.5707963267948966", "genserkins.alpha-5 -1.5707963267948966"}}),
    [](const ::testing::TestParamInfo<Case>& info) {
      std::string n = info.param.load;
      n = n.substr(0, n.find(' '));
      for (char& c : n) {
        if (c == '-') c = '_';
      }
      return n;
    });
