#include <gtest/gtest.h>

#include "core/hal/component.hpp"

using namespace cnc::hal;

namespace {
class Dummy : public Component {
 public:
  explicit Dummy(Hal& hal, const std::string& name = "dummy") : Component(hal, name) {
    out = make_pin<double>(name + ".out", PinDir::Out, 1.5);
    in = make_pin<double>(name + ".in", PinDir::In);
    in2 = make_pin<double>(name + ".in2", PinDir::In, 7.0);
    bit_in = make_pin<bool>(name + ".enable", PinDir::In);
    io = make_pin<int32_t>(name + ".io", PinDir::IO);
    gain = make_param<double>(name + ".gain", ParamDir::RW, 2.0);
    count = make_param<uint32_t>(name + ".count", ParamDir::RO, 3);
  }
  FloatPin out, in, in2;
  BitPin bit_in;
  S32Pin io;
  Param<double> gain;
  Param<uint32_t> count;
};

std::string error_of(const std::function<void()>& f) {
  try {
    f();
  } catch (const HalError& e) {
    return e.what();
  }
  return "(no error)";
}
}  // namespace

TEST(HalNames, ChapterTwoRules) {
  EXPECT_EQ(check_name("cia402.0.drive.03.statusword"), "");
  EXPECT_EQ(check_name("joint.0.motor-pos-cmd"), "");
  EXPECT_NE(check_name("Joint.0.pos"), "");
  EXPECT_NE(check_name("joint_0.pos"), "");
  EXPECT_NE(check_name("joint..pos"), "");
  EXPECT_NE(check_name(".joint"), "");
  EXPECT_NE(check_name(std::string(42, 'a')), "");
  EXPECT_EQ(check_name(std::string(41, 'a')), "");
  EXPECT_EQ(check_signal_name("X_pos-cmd"), "") << "signal names may use LinuxCNC config habits";
  EXPECT_NE(check_signal_name("x pos"), "");
}

TEST(Hal, PinsStartWithInitialValuesAndCarryTypes) {
  Hal hal;
  auto& d = static_cast<Dummy&>(hal.add_component(std::make_unique<Dummy>(hal)));
  EXPECT_EQ(d.out.get(), 1.5);
  EXPECT_EQ(d.in2.get(), 7.0);
  EXPECT_EQ(hal.get_value("dummy.out"), "1.5");
  EXPECT_EQ(hal.get_value("dummy.enable"), "FALSE");
  EXPECT_EQ(hal.get_value("dummy.gain"), "2");
  EXPECT_EQ(hal.type_of_name("dummy.io"), Type::S32);
}

TEST(Hal, DuplicateAndBadNamesAreRefused) {
  Hal hal;
  hal.add_component(std::make_unique<Dummy>(hal));
  EXPECT_NE(error_of([&] { hal.add_component(std::make_unique<Dummy>(hal)); }).find("already exists"),
            std::string::npos);
  EXPECT_NE(error_of([&] { hal.new_pin<bool>(nullptr, "Bad_Name", PinDir::In); }).find("pin name"), std::string::npos);
}

TEST(Hal, NetLinksPinsAndValuesFlow) {
  Hal hal;
  auto& d = static_cast<Dummy&>(hal.add_component(std::make_unique<Dummy>(hal)));
  hal.net("x-pos", {"dummy.out", "dummy.in"});
  EXPECT_EQ(d.in.get(), 1.5) << "a new writer brings its value";
  d.out.set(3.25);
  EXPECT_EQ(d.in.get(), 3.25);
  EXPECT_EQ(hal.get_signal("x-pos"), "3.25");
  // Adding a reader later joins the same signal.
  hal.net("x-pos", {"dummy.in2"});
  EXPECT_EQ(d.in2.get(), 3.25);
}

TEST(Hal, NetChecksTypesWritersAndExistingLinks) {
  Hal hal;
  hal.add_component(std::make_unique<Dummy>(hal, "a"));
  hal.add_component(std::make_unique<Dummy>(hal, "b"));
  EXPECT_EQ(error_of([&] { hal.net("s", {"a.out", "a.enable"}); }), "pin a.enable is bit but signal s is float");
  EXPECT_THROW(hal.get_signal("s"), HalError) << "a failing net creates nothing";
  EXPECT_EQ(error_of([&] { hal.net("s", {"a.out", "b.out"}); }), "signal s would have more than one output pin writing it");
  hal.net("s", {"a.out", "a.in"});
  EXPECT_EQ(error_of([&] { hal.net("t", {"b.out", "a.in"}); }), "pin a.in is already linked to signal s");
  EXPECT_EQ(error_of([&] { hal.net("u", {"nothing.here"}); }), "pin \"nothing.here\" does not exist");
  EXPECT_EQ(error_of([&] { hal.net("a.in2", {"a.in"}); }), "net: \"a.in2\" is a pin; the first name after 'net' is the signal");
}

TEST(Hal, SetpRules) {
  Hal hal;
  auto& d = static_cast<Dummy&>(hal.add_component(std::make_unique<Dummy>(hal)));
  hal.set_value("dummy.in", "4.5");
  EXPECT_EQ(d.in.get(), 4.5);
  hal.set_value("dummy.enable", "TRUE");
  EXPECT_TRUE(d.bit_in.get());
  hal.set_value("dummy.gain", "0.5");
  EXPECT_EQ(d.gain.get(), 0.5);
  EXPECT_EQ(error_of([&] { hal.set_value("dummy.out", "1"); }),
            "pin dummy.out is an output; only inputs and parameters can be set");
  EXPECT_EQ(error_of([&] { hal.set_value("dummy.count", "1"); }), "parameter dummy.count is read-only");
  EXPECT_EQ(error_of([&] { hal.set_value("dummy.in", "abc"); }), "value \"abc\" is not a valid float for pin dummy.in");
  EXPECT_EQ(error_of([&] { hal.set_value("dummy.io", "3000000000"); }), "value \"3000000000\" is not a valid s32 for pin dummy.io");
  hal.net("sig", {"dummy.out", "dummy.in"});
  EXPECT_EQ(error_of([&] { hal.set_value("dummy.in", "1"); }),
            "pin dummy.in is connected to signal sig; use sets on the signal");
}

TEST(Hal, SetsOnlyWithoutWriter) {
  Hal hal;
  auto& d = static_cast<Dummy&>(hal.add_component(std::make_unique<Dummy>(hal)));
  hal.net("free", {"dummy.in"});
  hal.set_signal("free", "9");
  EXPECT_EQ(d.in.get(), 9.0);
  hal.net("driven", {"dummy.out", "dummy.in2"});
  EXPECT_EQ(error_of([&] { hal.set_signal("driven", "1"); }),
            "signal driven is written by pin dummy.out; sets would be overwritten");
}

TEST(Hal, UnlinkKeepsTheLastValue) {
  Hal hal;
  auto& d = static_cast<Dummy&>(hal.add_component(std::make_unique<Dummy>(hal)));
  hal.net("s", {"dummy.out", "dummy.in"});
  d.out.set(6.0);
  hal.unlink("dummy.in");
  d.out.set(8.0);
  EXPECT_EQ(d.in.get(), 6.0);
  hal.set_value("dummy.in", "1");  // settable again
  EXPECT_EQ(d.in.get(), 1.0);
}

TEST(Hal, DeleteSignalUnlinksEveryPin) {
  Hal hal;
  auto& d = static_cast<Dummy&>(hal.add_component(std::make_unique<Dummy>(hal)));
  hal.net("s", {"dummy.out", "dummy.in", "dummy.in2"});
  hal.delete_signal("s");
  EXPECT_EQ(hal.pins()[0].signal, "");
  d.out.set(42);
  EXPECT_NE(d.in.get(), 42);
  EXPECT_THROW(hal.get_signal("s"), HalError);
}

TEST(Hal, IoPinsShareASignalButNotWithAnOutput) {
  Hal hal;
  hal.add_component(std::make_unique<Dummy>(hal, "a"));
  hal.add_component(std::make_unique<Dummy>(hal, "b"));
  hal.net("bus", {"a.io", "b.io"});
  hal.set_signal("bus", "5");
  EXPECT_EQ(hal.get_value("b.io"), "5");
  hal.add_component(std::make_unique<Dummy>(hal, "c"));
  hal.new_pin<int32_t>(nullptr, "c.s32-out", PinDir::Out);
  EXPECT_EQ(error_of([&] { hal.net("bus", {"c.s32-out"}); }), "signal bus would have both an output pin and I/O pins");
}

TEST(Hal, LinkPinsCreatesSignalNamedAfterWriter) {
  Hal hal;
  hal.add_component(std::make_unique<Dummy>(hal));
  hal.link_pins("dummy.in", "dummy.out");
  const auto sigs = hal.signals();
  ASSERT_EQ(sigs.size(), 1u);
  EXPECT_EQ(sigs[0].name, "dummy.out") << "LinuxCNC names the signal after the writing pin";
  EXPECT_EQ(sigs[0].writer, "dummy.out");
}
