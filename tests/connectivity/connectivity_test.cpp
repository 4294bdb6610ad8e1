// The MTConnect agent's model and the MQTT bridge's command checks, without
// a controller or a network (the end-to-end tests are the pytest files).
#include <gtest/gtest.h>

#include <stdexcept>

#include "connectivity/mqtt/bridge.hpp"
#include "connectivity/mtconnect/agent.hpp"
#include "core/ipc/operator_commands.hpp"

using namespace cnc;

namespace {

ipc::Status estop_status() {
  ipc::Status s{};
  s.task.state = ipc::TaskState::Estop;
  s.motion.axis_mask = 0x7;
  return s;
}

int count(const std::string& text, const std::string& what) {
  int n = 0;
  for (auto at = text.find(what); at != std::string::npos; at = text.find(what, at + 1)) ++n;
  return n;
}

}  // namespace

TEST(MtconnectAgent, EveryItemStartsUnavailableWithSequencesFromOne) {
  mtconnect::Agent agent({});
  EXPECT_EQ(agent.first_sequence(), 1u);
  EXPECT_EQ(agent.next_sequence(), agent.items().size() + 1);
  const std::string cur = agent.current(1);
  EXPECT_NE(cur.find("<Availability dataItemId=\"avail\""), std::string::npos);
  EXPECT_NE(cur.find(">UNAVAILABLE</Availability>"), std::string::npos);
  EXPECT_NE(cur.find("<Unavailable dataItemId=\"system\""), std::string::npos);
}

TEST(MtconnectAgent, AStatusAddsObservationsOnlyForValuesThatChanged) {
  mtconnect::Agent agent({});
  ipc::Status s = estop_status();
  agent.update(&s, 10);
  const uint64_t after_first = agent.next_sequence();
  agent.update(&s, 20);
  EXPECT_EQ(agent.next_sequence(), after_first);
  s.motion.actual_position[0] = 12.5;
  agent.update(&s, 30);
  EXPECT_EQ(agent.next_sequence(), after_first + 1);
  int status = 0;
  const std::string x = agent.sample(after_first, 10, 40, status);
  EXPECT_EQ(status, 200);
  EXPECT_NE(x.find(">12.5000</Position>"), std::string::npos);
  EXPECT_EQ(count(x, "sequence=\""), 1);
}

TEST(MtconnectAgent, SampleOutsideTheBufferIsAnOutOfRangeError) {
  mtconnect::AgentOptions opt;
  opt.buffer_size = 16;
  mtconnect::Agent agent(opt);
  ipc::Status s = estop_status();
  for (int i = 0; i < 40; ++i) {
    s.motion.actual_position[0] = i;
    agent.update(&s, 100 + i);
  }
  EXPECT_GT(agent.first_sequence(), 1u);
  int status = 0;
  const std::string x = agent.sample(1, 10, 200, status);
  EXPECT_EQ(status, 400);
  EXPECT_NE(x.find("errorCode=\"OUT_OF_RANGE\""), std::string::npos);
  agent.sample(agent.first_sequence(), 10, 200, status);
  EXPECT_EQ(status, 200);
  agent.sample(agent.first_sequence(), 17, 200, status);
  EXPECT_EQ(status, 400);
}

TEST(MtconnectAgent, AnErrorMessageIsAFaultUntilEstopReset) {
  mtconnect::Agent agent({});
  ipc::Status s = estop_status();
  agent.update(&s, 10);
  Message m;
  m.kind = MessageKind::Error;
  m.source.assign("motion");
  m.text.assign("joint 1 following error < 5 & more");
  agent.message(m, 11);
  agent.update(&s, 12);
  std::string cur = agent.current(13);
  EXPECT_NE(cur.find("<Fault dataItemId=\"system\""), std::string::npos);
  EXPECT_NE(cur.find("nativeCode=\"motion\""), std::string::npos);
  EXPECT_NE(cur.find("following error &lt; 5 &amp; more</Fault>"), std::string::npos);
  s.task.state = ipc::TaskState::EstopReset;
  agent.update(&s, 14);
  cur = agent.current(15);
  EXPECT_NE(cur.find("<Normal dataItemId=\"system\""), std::string::npos);
}

TEST(MtconnectAgent, TheControllerGoingAwayMakesEverythingUnavailable) {
  mtconnect::Agent agent({});
  ipc::Status s = estop_status();
  agent.update(&s, 10);
  EXPECT_NE(agent.current(11).find(">AVAILABLE</Availability>"), std::string::npos);
  agent.update(nullptr, 12);
  EXPECT_NE(agent.current(13).find(">UNAVAILABLE</Availability>"), std::string::npos);
}

TEST(MqttCommands, AWrongOrMissingTokenIsRefused) {
  const std::set<std::string> allowed = {"on"};
  EXPECT_THROW(mqtt::parse_command(R"({"command":"on","token":"nope"})", "secret", allowed), std::invalid_argument);
  EXPECT_THROW(mqtt::parse_command(R"({"command":"on","token":"secreT"})", "secret", allowed), std::invalid_argument);
  EXPECT_NO_THROW(mqtt::parse_command(R"({"command":"on","token":"secret"})", "secret", allowed));
  EXPECT_THROW(mqtt::parse_command(R"({"command":"on"})", "secret", allowed), std::invalid_argument);
  // No token configured: nothing is ever accepted.
  EXPECT_THROW(mqtt::parse_command(R"({"command":"on","token":""})", "", allowed), std::invalid_argument);
}

TEST(MqttCommands, ACommandOutsideTheWhitelistIsRefused) {
  try {
    mqtt::parse_command(R"({"command":"mdi","args":["G0 X1"],"token":"t"})", "t", {"on"});
    FAIL() << "accepted";
  } catch (const std::invalid_argument& e) {
    EXPECT_NE(std::string(e.what()).find("whitelist"), std::string::npos);
  }
}

TEST(MqttCommands, AnAllowedCommandIsEncodedAsTheChannelWantsIt) {
  const auto r = mqtt::parse_command(R"({"id":7,"command":"mdi","args":["G0 X1"],"token":"t"})", "t", {"mdi"});
  EXPECT_EQ(r.id, "7");
  EXPECT_EQ(r.command.type, ipc::CommandType::TaskPlanExecute);
  EXPECT_EQ(r.command.i[0], -1);
  EXPECT_EQ(std::string(r.command.text.c_str()), "G0 X1");
  const auto f = mqtt::parse_command(R"({"command":"feed-override","args":[50],"token":"t"})", "t", {"feed-override"});
  EXPECT_DOUBLE_EQ(f.command.d[0], 0.5);
  EXPECT_THROW(mqtt::parse_command(R"({"command":"open","args":["rel.ngc"],"token":"t"})", "t", {"open"}),
               std::invalid_argument);
}

TEST(OperatorCommands, AnIncrementalJogTakesItsDirectionFromTheVelocity) {
  const ipc::Command c = ipc::commands::jog_increment(0, false, -10, 2.5);
  EXPECT_EQ(c.type, ipc::CommandType::JogIncr);
  EXPECT_DOUBLE_EQ(c.d[0], 10);
  EXPECT_DOUBLE_EQ(c.d[1], -2.5);
  EXPECT_EQ(c.i[1], 0);
}

TEST(OperatorCommands, TooLongATextIsRefusedNamingIt) {
  try {
    ipc::commands::mdi(std::string(2000, 'G'));
    FAIL() << "accepted";
  } catch (const std::invalid_argument& e) {
    EXPECT_NE(std::string(e.what()).find("MDI line"), std::string::npos);
  }
}
