// The scope page's logic (hmi/scope_view.*): the halcmd lines it sends to
// the controller's HAL scope and the reading of its state and CSV.
#include <QtTest>

#include "hmi/scope_view.hpp"

using namespace cnc::hmi::scope;

class ScopeViewTests : public QObject {
  Q_OBJECT
 private slots:
  void pinsAreSplitOnCommasAndBlanks() {
    QCOMPARE(split_pins(" a.b , c.d\te-f,,"), (std::vector<std::string>{"a.b", "c.d", "e-f"}));
  }

  void setupLineCarriesTriggerEdgeLevelPreSamplesAndMode() {
    Settings s;
    s.pins = {"joint.0.pos-fb", "joint.0.f-error"};
    s.trigger = "joint.0.vel-cmd";
    s.edge = Edge::Falling;
    s.level = -2.5;
    s.pre_percent = 25;
    s.samples = 500;
    s.mode = Mode::Normal;
    QCOMPARE(setup_line(s), std::string("scope setup joint.0.pos-fb,joint.0.f-error trigger=joint.0.vel-cmd edge=falling "
                                        "level=-2.5 pre=25 samples=500 mode=normal"));
    s.trigger.clear();
    s.samples = 0;
    s.mode = Mode::Auto;
    QCOMPARE(setup_line(s), std::string("scope setup joint.0.pos-fb,joint.0.f-error pre=25 mode=auto"));
  }

  void setupRefusesWhatTheScopeCannotRecordNamingTheField() {
    Settings s;
    QVERIFY_THROWS_EXCEPTION(std::invalid_argument, setup_line(s));  // no pins
    for (int i = 0; i < 16; ++i) s.pins.push_back("p." + std::to_string(i));
    QVERIFY(!setup_line(s).empty());
    s.trigger = "t.x";  // the 17th channel
    try {
      setup_line(s);
      QFAIL("17 channels accepted");
    } catch (const std::invalid_argument& e) {
      QVERIFY2(std::string(e.what()).find("17 channels") != std::string::npos, e.what());
    }
    Settings bad;
    bad.pins = {"a=b"};
    QVERIFY_THROWS_EXCEPTION(std::invalid_argument, setup_line(bad));
    bad.pins = {"a"};
    bad.pre_percent = 101;
    QVERIFY_THROWS_EXCEPTION(std::invalid_argument, setup_line(bad));
    bad.pre_percent = 10;
    bad.samples = 1;
    QVERIFY_THROWS_EXCEPTION(std::invalid_argument, setup_line(bad));
  }

  void stateLinesAreRead() {
    const State w = parse_state("waiting samples=2000 pre=200 channels=3\n");
    QCOMPARE(w.name, std::string("waiting"));
    QCOMPARE(w.samples, 2000);
    QCOMPARE(w.pre, 200);
    QCOMPARE(w.channels, 3);
    QVERIFY(!w.done() && !w.forced);
    const State d = parse_state("done samples=10 pre=1 channels=1 forced");
    QVERIFY(d.done() && d.forced);
    QVERIFY_THROWS_EXCEPTION(std::invalid_argument, parse_state("scope: no scope loaded"));
  }

  void csvIsReadIntoTimeAndOneColumnPerPinAndKeptAsSent() {
    const std::string text = "time_s,a.b,c.d\n-0.002000,1,2.5\n-0.001000,1.5,2.5e-3\n0.000000,2,-1\n";
    const Capture c = parse_csv(text);
    QCOMPARE(c.names, (std::vector<std::string>{"a.b", "c.d"}));
    QCOMPARE(c.time, (std::vector<double>{-0.002, -0.001, 0.0}));
    QCOMPARE(c.columns[0], (std::vector<double>{1, 1.5, 2}));
    QCOMPARE(c.columns[1][1], 0.0025);
    QCOMPARE(c.csv, text);
    try {
      parse_csv("time_s,a\n0,1\n0.001,x\n");
      QFAIL("a bad row was accepted");
    } catch (const std::invalid_argument& e) {
      QVERIFY2(std::string(e.what()).find("line 3") != std::string::npos, e.what());
    }
    QVERIFY_THROWS_EXCEPTION(std::invalid_argument, parse_csv("a,b\n"));
  }
};

QTEST_GUILESS_MAIN(ScopeViewTests)
#include "scope_view_tests.moc"
