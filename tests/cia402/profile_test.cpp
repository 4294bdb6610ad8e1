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

TEST(Cia402Profile, DecodesTheCommandsOfTheControlword) {
  EXPECT_EQ(decode_command(0x0006), Command::Shutdown);
  EXPECT_EQ(decode_command(0x000E), Command::Shutdown);  // bit 3 is "x"
  EXPECT_EQ(decode_command(0x0007), Command::SwitchOn);
  EXPECT_EQ(decode_command(0x000F), Command::EnableOperation);
  EXPECT_EQ(decode_command(0x0000), Command::DisableVoltage);
  EXPECT_EQ(decode_command(0x000D), Command::DisableVoltage);
  EXPECT_EQ(decode_command(0x0002), Command::QuickStop);
  EXPECT_EQ(decode_command(0x000B), Command::QuickStop);
  EXPECT_EQ(decode_command(0x008F), Command::EnableOperation);  // the fault reset bit is apart
}

TEST(Cia402Profile, TransitionTableMatchesTheProfile) {
  struct T {
    int number;
    State from;
    Command c;
    bool stays;
    State to;
  };
  const T table[] = {
      {2, State::SwitchOnDisabled, Command::Shutdown, false, State::ReadyToSwitchOn},
      {3, State::ReadyToSwitchOn, Command::SwitchOn, false, State::SwitchedOn},
      {4, State::SwitchedOn, Command::EnableOperation, false, State::OperationEnabled},
      {5, State::OperationEnabled, Command::SwitchOn, false, State::SwitchedOn},
      {6, State::SwitchedOn, Command::Shutdown, false, State::ReadyToSwitchOn},
      {7, State::ReadyToSwitchOn, Command::QuickStop, false, State::SwitchOnDisabled},
      {7, State::ReadyToSwitchOn, Command::DisableVoltage, false, State::SwitchOnDisabled},
      {8, State::OperationEnabled, Command::Shutdown, false, State::ReadyToSwitchOn},
      {9, State::OperationEnabled, Command::DisableVoltage, false, State::SwitchOnDisabled},
      {10, State::SwitchedOn, Command::QuickStop, false, State::SwitchOnDisabled},
      {10, State::SwitchedOn, Command::DisableVoltage, false, State::SwitchOnDisabled},
      {11, State::OperationEnabled, Command::QuickStop, false, State::QuickStopActive},
      {12, State::QuickStopActive, Command::DisableVoltage, false, State::SwitchOnDisabled},
      {16, State::QuickStopActive, Command::EnableOperation, true, State::OperationEnabled},
      {0, State::QuickStopActive, Command::EnableOperation, false, State::QuickStopActive},  // options 0-4
      {0, State::SwitchOnDisabled, Command::EnableOperation, false, State::SwitchOnDisabled},
      {0, State::Fault, Command::Shutdown, false, State::Fault},  // only the reset edge leaves a fault
  };
  for (const T& t : table) {
    EXPECT_EQ(next_state(t.from, t.c, t.stays), t.to) << "T" << t.number << " from " << to_string(t.from) << " on "
                                                      << to_string(t.c);
  }
}

TEST(Cia402Profile, HomingStatusFromBits13_12_10) {
  EXPECT_EQ(decode_homing(0x0000), HomingStatus::InProgress);
  EXPECT_EQ(decode_homing(0x0400), HomingStatus::Interrupted);
  EXPECT_EQ(decode_homing(0x1000), HomingStatus::AttainedNotReached);
  EXPECT_EQ(decode_homing(0x1400), HomingStatus::Completed);
  EXPECT_EQ(decode_homing(0x2000), HomingStatus::ErrorMoving);
  EXPECT_EQ(decode_homing(0x2400), HomingStatus::ErrorStopped);
  for (HomingStatus h : {HomingStatus::InProgress, HomingStatus::Interrupted, HomingStatus::AttainedNotReached,
                         HomingStatus::Completed, HomingStatus::ErrorMoving, HomingStatus::ErrorStopped}) {
    EXPECT_EQ(decode_homing(homing_bits(h)), h);
  }
}

TEST(Cia402Profile, ModesParseByNameOrNumber) {
  Mode m = Mode::None;
  EXPECT_TRUE(parse_mode("csp", m));
  EXPECT_EQ(m, Mode::CyclicSyncPosition);
  EXPECT_TRUE(parse_mode("9", m));
  EXPECT_EQ(m, Mode::CyclicSyncVelocity);
  EXPECT_FALSE(parse_mode("CSPX", m));
  EXPECT_FALSE(parse_mode("5", m));
  EXPECT_EQ(supported_mode_bit(Mode::Homing), 5);
  EXPECT_EQ(supported_mode_bit(Mode::CyclicSyncTorque), 9);
}

TEST(Cia402ErrorCodes, KnownCodesReadAsText) {
  EXPECT_STREQ(error_code_text(0x8611), "following error");
  EXPECT_STREQ(error_code_text(0x2310), "continuous over-current");
  EXPECT_STREQ(error_code_text(0x7305), "incremental encoder 1 broken");
  EXPECT_STREQ(error_code_text(0x3210), "DC-link over-voltage");
  EXPECT_STREQ(error_code_text(0x4210), "device over-temperature");
  EXPECT_STREQ(error_code_text(0x6320), "parameter error");
  EXPECT_STREQ(error_code_text(0x8130), "life guard or heartbeat error");
  EXPECT_STREQ(error_code_text(0x8250), "RPDO timeout");
  EXPECT_STREQ(error_code_text(0x8612), "reference limit");
  EXPECT_STREQ(error_code_text(0x9000), "external error");
  EXPECT_STREQ(error_code_text(0x0000), "error reset or no error");
}

TEST(Cia402ErrorCodes, UnknownCodesReadAsTheirClass) {
  EXPECT_STREQ(error_code_text(0x2399), "current, device output side");
  EXPECT_STREQ(error_code_text(0x3299), "voltage inside the device");
  EXPECT_STREQ(error_code_text(0x4321), "temperature");
  EXPECT_STREQ(error_code_text(0x5531), "device hardware");
  EXPECT_STREQ(error_code_text(0x8199), "monitoring: communication");
  EXPECT_STREQ(error_code_text(0xFF77), "device specific");
  EXPECT_STREQ(error_code_text(0xF100), "additional functions");
}

TEST(Cia402Profile, HomingMethodsDefinedByTheProfile) {
  for (int m : {1, 14, 17, 30, 33, 34, 35, 37, -1, -128}) EXPECT_TRUE(is_defined_homing_method(m)) << m;
  for (int m : {0, 15, 16, 31, 32, 36, 38, -129}) EXPECT_FALSE(is_defined_homing_method(m)) << m;
}
