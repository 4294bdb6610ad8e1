#include <gtest/gtest.h>

#include "cia402/profile.hpp"

using namespace cnc::cia402;

TEST(Cia402Profile, DecodesEveryStatePattern) {
  EXPECT_EQ(decode_state(0x0000), State::NotReadyToSwitchOn);
  EXPECT_EQ(decode_state(0x0250), State::SwitchOnDisabled);
  EXPECT_EQ(decode_state(0x0231), State::ReadyToSwitchOn);
  EXPECT_EQ(decode_state(0x0233), State::SwitchedOn);
  EXPECT_EQ(decode_state(0x1237), State::OperationEnabled);
  EXPECT_EQ(decode_state(0x0217), State::QuickStopActive);
  EXPECT_EQ(decode_state(0x021F), State::FaultReactionActive);
  EXPECT_EQ(decode_state(0x0218), State::Fault);
  EXPECT_EQ(decode_state(0x12B7), State::OperationEnabled);  // warning set: still enabled
  EXPECT_EQ(decode_state(0x0001), State::Invalid);
  EXPECT_EQ(decode_state(0x0045), State::Invalid);
}
