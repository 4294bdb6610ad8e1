#include <gtest/gtest.h>

#include <functional>

#include "core/tooltable/tool_table.hpp"
#include "core/util/error.hpp"
#include "tests/support/testing.hpp"

using cnc::ConfigError;
using cnc::tooltable::ChangerKind;
using cnc::tooltable::Tool;
using cnc::tooltable::ToolTable;

namespace {
std::string error_of(const std::function<void()>& f) {
  try {
    f();
  } catch (const ConfigError& e) {
    return e.what();
  }
  return "(no error)";
}

const char* kTable =
    "T1 P1 Z+1.5 D6.0 ;6mm mill\n"
    "; a comment line\n"
    "\n"
    "t2 p5 z2.5 d3 x-0.25\n"
    "T7 P9 X0.1 Z5 D10 I80 J-10 Q3 ;lathe tool\n";
}  // namespace

TEST(ToolTable, ParsesWordsCommentsAndCompactsPocketsForNonRandom) {
  const auto t = ToolTable::parse(kTable, "t.tbl", ChangerKind::NonRandom);
  ASSERT_EQ(t.size(), 4);
  EXPECT_TRUE(t.spindle().is_empty());
  EXPECT_EQ(t.at(1).number, 1);
  EXPECT_EQ(t.at(1).comment, "6mm mill");
  EXPECT_DOUBLE_EQ(t.at(1).offset.z(), 1.5);
  EXPECT_DOUBLE_EQ(t.at(1).diameter, 6.0);
  EXPECT_EQ(t.at(2).number, 2);
  EXPECT_EQ(t.at(2).pocket, 5);
  EXPECT_DOUBLE_EQ(t.at(2).offset.x(), -0.25);
  EXPECT_EQ(t.at(3).orientation, 3);
  EXPECT_DOUBLE_EQ(t.at(3).front_angle, 80);
  EXPECT_DOUBLE_EQ(t.at(3).back_angle, -10);
  EXPECT_EQ(t.find_tool(7), 3);
  EXPECT_EQ(t.find_pocket(9), 3);
  EXPECT_FALSE(t.find_tool(4));
}

TEST(ToolTable, RandomIndexIsThePocketAndPocketZeroIsTheSpindle) {
  const auto t = ToolTable::parse("T0 P3\nT4 P0 Z1\nT9 P12\n", "r.tbl", ChangerKind::Random);
  EXPECT_EQ(t.spindle().number, 4);
  EXPECT_EQ(t.find_tool(9), 12);
  EXPECT_EQ(t.find_tool(0), 3);
  EXPECT_FALSE(t.find_tool(4)) << "the spindle is not a pocket";
  EXPECT_EQ(t.find_tool_anywhere(4), 0);
}

TEST(ToolTable, ErrorsNameFileLineAndWhatWasExpected) {
  auto nr = [](const char* text) { return error_of([&] { ToolTable::parse(text, "t.tbl", ChangerKind::NonRandom); }); };
  auto rnd = [](const char* text) { return error_of([&] { ToolTable::parse(text, "t.tbl", ChangerKind::Random); }); };
  EXPECT_EQ(nr("T1 P1\nT2 P2 Zx\n"), "t.tbl:2: bad number 'x' after Z, expected a real number");
  EXPECT_EQ(nr("T1 P1 K3\n"), "t.tbl:1: unexpected word 'K3', expected T, P, X Y Z A B C U V W, D, I, J, Q or a ;comment");
  EXPECT_EQ(nr("P1 Z1\n"), "t.tbl:1: missing T word (tool number)");
  EXPECT_EQ(nr("T1 Z1\n"), "t.tbl:1: missing P word (pocket number)");
  EXPECT_EQ(nr("T0 P1\n"), "t.tbl:1: tool number T0 not allowed, expected a positive number (T0 means no tool)");
  EXPECT_EQ(nr("T1 P0\n"), "t.tbl:1: pocket P0 not allowed, expected a positive pocket number");
  EXPECT_EQ(nr("T1 P1\nT1 P2\n"), "t.tbl:2: tool T1 defined twice");
  EXPECT_EQ(nr("T1 P1\nT2 P1\n"), "t.tbl:2: pocket P1 used twice");
  EXPECT_EQ(nr("T1 P1 Z1 Z2\n"), "t.tbl:1: word Z appears twice");
  EXPECT_EQ(nr("T1 P1 Q12\n"), "t.tbl:1: orientation Q12 out of range, expected 0 to 9");
  EXPECT_EQ(nr("T1.5 P1\n"), "t.tbl:1: bad number '1.5' after T, expected an integer");
  EXPECT_EQ(nr("T1 P\n"), "t.tbl:1: missing value after P");
  EXPECT_EQ(rnd("T1 P1001\n"), "t.tbl:1: pocket P1001 out of range, expected 0 to 1000");
  EXPECT_EQ(rnd("T-1 P1\n"), "t.tbl:1: tool number T-1 is negative");
  EXPECT_EQ(rnd("T0 P1\n"), "(no error)");
}

TEST(ToolTable, LoadOfMissingFileNamesIt) {
  cnc::testing::TempDir dir;
  const std::string msg = error_of([&] { ToolTable::load(dir / "none.tbl", ChangerKind::NonRandom); });
  EXPECT_NE(msg.find((dir / "none.tbl").string() + ": cannot read tool table"), std::string::npos) << msg;
}

TEST(ToolTable, SaveWritesAtomicallyAndReadsBack) {
  cnc::testing::TempDir dir;
  const auto t = ToolTable::parse(kTable, "t.tbl", ChangerKind::NonRandom);
  t.save(dir / "out.tbl");
  const auto back = ToolTable::load(dir / "out.tbl", ChangerKind::NonRandom);
  ASSERT_EQ(back.size(), t.size());
  for (int i = 1; i < t.size(); ++i) EXPECT_EQ(back.at(i), t.at(i)) << "index " << i;
  EXPECT_EQ(t.to_text().substr(0, 41), "T1 P1 Z+1.500000 D+6.000000 ;6mm mill\nT2 ");
  EXPECT_FALSE(std::filesystem::exists(dir / "out.tbl.tmp"));
}

TEST(ToolTable, NonRandomChangeCopiesIntoSpindleAndKeepsHomePocket) {
  auto t = ToolTable::parse(kTable, "t.tbl", ChangerKind::NonRandom);
  t.change_tool(2);
  EXPECT_EQ(t.spindle().number, 2);
  EXPECT_EQ(t.spindle().pocket, 5);
  EXPECT_EQ(t.at(2).number, 2) << "the home pocket keeps its tool";
  t.change_tool(0);
  EXPECT_EQ(t.spindle().number, 0) << "T0 M6 empties the spindle";
  EXPECT_DOUBLE_EQ(t.spindle().offset.z(), 0);
}

TEST(ToolTable, RandomChangeSwapsSpindleToolIntoThePocket) {
  auto t = ToolTable::parse("T1 P1 Z1\nT2 P2 Z2\n", "r.tbl", ChangerKind::Random);
  t.change_tool(1);
  EXPECT_EQ(t.spindle().number, 1);
  EXPECT_EQ(t.spindle().pocket, 0);
  EXPECT_TRUE(t.at(1).is_empty());
  t.change_tool(2);
  EXPECT_EQ(t.spindle().number, 2);
  EXPECT_EQ(t.at(2).number, 1) << "tool 1 went into pocket 2";
  EXPECT_EQ(t.at(2).pocket, 2);
  EXPECT_EQ(t.to_text(), "T2 P0 Z+2.000000 ;\nT1 P2 Z+1.000000 ;\n");
}

TEST(ToolTable, UpdateOfLoadedToolRefreshesSpindleOnlyForThatTool) {
  auto t = ToolTable::parse(kTable, "t.tbl", ChangerKind::NonRandom);
  t.change_tool(1);
  Tool other = t.at(2);
  other.offset[2] = 9;
  EXPECT_EQ(t.update_tool(other), 2);
  EXPECT_DOUBLE_EQ(t.spindle().offset.z(), 1.5) << "another tool's update leaves the spindle alone";
  Tool loaded = t.at(1);
  loaded.offset[2] = 4;
  EXPECT_EQ(t.update_tool(loaded), 1);
  EXPECT_DOUBLE_EQ(t.spindle().offset.z(), 4);
  EXPECT_DOUBLE_EQ(t.at(1).offset.z(), 4);
}

TEST(ToolTable, RandomUpdateOfLoadedToolWritesOnlyTheSpindle) {
  auto t = ToolTable::parse("T1 P1 Z1\nT2 P2 Z2\n", "r.tbl", ChangerKind::Random);
  t.change_tool(1);
  Tool loaded = t.spindle();
  loaded.offset[2] = 7;
  EXPECT_EQ(t.update_tool(loaded), 0);
  EXPECT_DOUBLE_EQ(t.spindle().offset.z(), 7);
  EXPECT_TRUE(t.at(1).is_empty());
}

TEST(ToolTable, UpdateOfUnknownToolAddsIt) {
  auto t = ToolTable::parse(kTable, "t.tbl", ChangerKind::NonRandom);
  Tool n;
  n.number = 40;
  n.diameter = 2;
  const int idx = t.update_tool(n);
  EXPECT_EQ(idx, 4);
  EXPECT_EQ(t.find_tool(40), 4);
  EXPECT_EQ(t.at(4).pocket, 4);
}

TEST(ToolTable, SetSpindleToolCopiesWithoutMoving) {
  auto t = ToolTable::parse(kTable, "t.tbl", ChangerKind::NonRandom);
  t.set_spindle_tool(3);
  EXPECT_EQ(t.spindle().number, 7);
  EXPECT_EQ(t.at(3).number, 7);
  t.set_spindle_tool(0);
  EXPECT_EQ(t.spindle().number, 0);
}
