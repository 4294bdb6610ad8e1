// The controller's alarm table: one alarm per cause, identical messages
// merged with a count, acknowledgement kept for every client.
#include "core/ipc/alarms.hpp"

#include <gtest/gtest.h>

namespace cnc::ipc {
namespace {

Message error(std::string_view source, std::string_view text, int64_t t = 1) {
  Message m;
  m.time_ns = t;
  m.kind = MessageKind::Error;
  m.source.assign(source);
  m.text.assign(text);
  return m;
}

int used(const AlarmStatus& s) {
  int n = 0;
  for (const AlarmEntry& e : s.list) n += e.id != 0 ? 1 : 0;
  return n;
}

TEST(AlarmTable, OneDriveFaultIsOneActiveAlarmShowingTheExplicitCause) {
  AlarmTable t;
  t.post(error("motion", "joint 1 amplifier fault (joint.1.amp-fault-in)", 1));
  t.post(error("motion", "joint 1 amplifier fault (joint.1.amp-fault-in)", 2));
  t.post(error("task", "program aborted at line 12: joint 1 amplifier fault (joint.1.amp-fault-in); drive y: "
                       "0x2310 continuous over-current", 3));
  const AlarmStatus& s = t.status();
  EXPECT_TRUE(s.available);
  EXPECT_EQ(s.active, 1u);
  ASSERT_EQ(used(s), 1);
  EXPECT_EQ(s.list[0].count, 3u);
  EXPECT_EQ(s.list[0].cause.view(), "joint 1");
  EXPECT_NE(s.list[0].text.view().find("over-current"), std::string_view::npos);
  EXPECT_EQ(s.list[0].first_ns, 1);
  EXPECT_EQ(s.list[0].last_ns, 3);
}

TEST(AlarmTable, IdenticalMessagesMergeWithACountOthersStayApart) {
  AlarmTable t;
  t.post(error("iocontrol", "E-stop chain opened"));
  t.post(error("iocontrol", "E-stop chain opened"));
  t.post(error("interp", "p.ngc:3: unknown word"));
  t.post(error("motion", "joint 10 following error")); // not joint 1
  t.post(error("motion", "joint 1 following error"));
  const AlarmStatus& s = t.status();
  EXPECT_EQ(s.active, 4u);
  EXPECT_EQ(s.list[0].count, 2u);
  EXPECT_EQ(s.list[2].cause.view(), "joint 10");
  EXPECT_EQ(s.list[3].cause.view(), "joint 1");
}

TEST(AlarmTable, AcknowledgedAlarmsStayInactiveAndTheSameCauseRaisesANewOne) {
  AlarmTable t;
  t.post(error("motion", "joint 0 on its max limit switch"));
  t.post(error("interp", "bad line"));
  const uint32_t first = t.status().list[0].id;
  EXPECT_EQ(t.acknowledge(first, 10), 1);
  EXPECT_EQ(t.acknowledge(first, 11), 0);  // already
  EXPECT_EQ(t.acknowledge(999, 11), 0);    // unknown
  EXPECT_EQ(t.status().active, 1u);
  EXPECT_TRUE(t.status().list[0].acknowledged);
  EXPECT_EQ(t.status().list[0].acknowledged_ns, 10);
  t.post(error("motion", "joint 0 on its max limit switch"));
  EXPECT_EQ(t.status().active, 2u);
  EXPECT_EQ(t.acknowledge(0, 12), 2);
  EXPECT_EQ(t.status().active, 0u);
}

TEST(AlarmTable, TextsAndOtherKindsAreNotAlarms) {
  AlarmTable t;
  Message m = error("task", "machine off");
  m.kind = MessageKind::Text;
  t.post(m);
  m.kind = MessageKind::Display;
  t.post(m);
  EXPECT_EQ(used(t.status()), 0);
}

TEST(AlarmTable, AFullTableDropsTheOldestAcknowledgedFirst) {
  AlarmTable t;
  for (int i = 0; i < kMaxAlarms; ++i) t.post(error("x", "alarm " + std::to_string(i)));
  const uint32_t keep = t.status().list[0].id;
  t.acknowledge(t.status().list[3].id, 5);
  t.post(error("x", "one more"));
  const AlarmStatus& s = t.status();
  EXPECT_EQ(s.dropped, 1u);
  EXPECT_EQ(s.list[0].id, keep);
  EXPECT_EQ(s.list[kMaxAlarms - 1].text.view(), "one more");
  EXPECT_EQ(s.active, static_cast<uint32_t>(kMaxAlarms));
}

TEST(AlarmTable, TheCauseIsTheFirstJointOrSpindleNamed) {
  EXPECT_EQ(AlarmTable::cause_of("spindle 0 amplifier fault"), "spindle 0");
  EXPECT_EQ(AlarmTable::cause_of("program aborted at line 4: joint 2 following error"), "joint 2");
  EXPECT_EQ(AlarmTable::cause_of("adjoint 2 x"), "");
  EXPECT_EQ(AlarmTable::cause_of("joint amplifier"), "");
}

}  // namespace
}  // namespace cnc::ipc
