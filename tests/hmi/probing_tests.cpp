// The probing routines' logic (hmi/probing.*): the G-code each stage sends,
// the arithmetic of the results (tip radius, midpoints, diameters, tool
// length, origins for G10 L2) and the [PROBE] settings with their errors.
#include <QtTest>
#include <cmath>

#include "core/ini/ini_file.hpp"
#include "core/util/error.hpp"
#include "hmi/probing.hpp"

using namespace cnc;
using namespace cnc::hmi::probing;

namespace {

using Lines = std::vector<std::string>;

Settings settings() {
  Settings s;
  s.tip_diameter = 2;  // radius 1
  s.search_distance = 10;
  s.latch_distance = 1;
  s.search_feed = 300;
  s.latch_feed = 25;
  s.clearance = 4;
  s.setter = true;
  s.setter_x = 250;
  s.setter_y = 10;
  s.setter_z = -50;
  s.setter_safe_z = 0;
  s.setter_reference_z = -150;
  s.setter_search_distance = 80;
  return s;
}

Pose pose(double x, double y, double z) {
  Pose p;
  p[0] = x;
  p[1] = y;
  p[2] = z;
  return p;
}

Start at(double x, double y, double z) {
  Start s;
  s.position = pose(x, y, z);
  return s;
}

// Runs the routine with the given probe results (machine coordinate of the
// probed axis, in order); returns every line sent.
Lines run(Routine& r, const std::vector<double>& hits) {
  Lines all;
  std::size_t k = 0;
  while (!r.done()) {
    const Stage st = r.stage();
    all.insert(all.end(), st.lines.begin(), st.lines.end());
    Pose p;
    if (st.probe_axis >= 0) {
      if (k >= hits.size()) {
        r.completed(false, p);
        break;
      }
      p[st.probe_axis] = hits[k++];
    }
    r.completed(true, p);
  }
  return all;
}

std::string join(const Lines& l) {
  std::string s;
  for (const auto& x : l) s += x + "\n";
  return s;
}

}  // namespace

class ProbingTests : public QObject {
  Q_OBJECT
 private slots:
  void aProbeIsAFastSearchABackOffAndASlowTouchInRelativeMoves() {
    const Lines l = Routine::probe_lines(settings(), 0, -1, 10);
    QCOMPARE(join(l), std::string("G91 G38.2 X-10.0000 F300.0000\nG0 X1.0000\nG38.2 X-2.0000 F25.0000\nG0 X1.0000\nG90\n"));
  }

  void toolLengthGoesToTheSetterProbesDownAndSetsTheTableLengthFromTheReference() {
    Start st = at(100, 50, -20);
    st.tool_in_spindle = 3;
    Routine r(settings(), Request{.kind = Kind::ToolLength, .tool = 3}, st);
    const Lines l = run(r, {-112.5});
    QVERIFY2(!r.failed(), r.error().c_str());
    QCOMPARE(join(l), std::string("M70\nG21 G90 G94\nG53 G0 Z0.0000\nG53 G0 X250.0000 Y10.0000\nG53 G0 Z-50.0000\n"
                                  "G91 G38.2 Z-80.0000 F300.0000\nG0 Z1.0000\nG38.2 Z-2.0000 F25.0000\nG0 Z1.0000\nG90\n"
                                  "G53 G0 Z0.0000\nG10 L1 P3 Z37.5000\nG43 H3\nM72\nM71\n"));
    QCOMPARE(r.result().tool_length, 37.5);  // -112.5 - (-150)
    QVERIFY(r.result().summary.find("T3 length 37.5000") != std::string::npos);
  }

  void toolLengthOfAToolNotInTheSpindleDoesNotApplyIt() {
    Routine r(settings(), Request{.kind = Kind::ToolLength, .tool = 5}, at(0, 0, 0));
    const Lines l = run(r, {-140});
    QCOMPARE(l.at(l.size() - 3), std::string("G10 L1 P5 Z10.0000"));
  }

  void toolLengthWithoutASetterOrToolIsRefused() {
    Settings s = settings();
    s.setter = false;
    QVERIFY_THROWS_EXCEPTION(std::invalid_argument, Routine(s, Request{.kind = Kind::ToolLength, .tool = 1}, at(0, 0, 0)));
    QVERIFY_THROWS_EXCEPTION(std::invalid_argument, Routine(settings(), Request{.kind = Kind::ToolLength, .tool = 0}, at(0, 0, 0)));
  }

  void anEdgeIsTheProbeCentrePlusTheTipRadiusTowardTheMaterial() {
    Routine plus(settings(), Request{.kind = Kind::Edge, .axis = 0, .direction = 1}, at(0, 0, 0));
    run(plus, {20});
    QVERIFY(plus.result().has_x && !plus.result().has_y);
    QCOMPARE(plus.result().x, 21.0);
    Routine minus(settings(), Request{.kind = Kind::Edge, .axis = 1, .direction = -1}, at(0, 0, 0));
    const Lines l = run(minus, {-7});
    QCOMPARE(minus.result().y, -8.0);
    QCOMPARE(l.at(2), std::string("G91 G38.2 Y-10.0000 F300.0000"));
  }

  void anEdgeSetsTheOriginOfAnyCoordinateSystemSoThatItReadsTheValue() {
    Start st = at(0, 0, 0);
    st.g92_offset[0] = 2;
    st.tool_offset[0] = 0.5;
    Request q{.kind = Kind::Edge, .axis = 0, .direction = 1, .coordinate_system = 6};
    q.value_x = -3;
    Routine r(settings(), q, st);
    const Lines l = run(r, {20});
    // displayed = machine - origin - G92 - tool: 21 - origin - 2 - 0.5 = -3.
    QCOMPARE(l.at(l.size() - 3), std::string("G10 L2 P6 X21.5000"));
    QVERIFY(r.result().summary.find("G59 set") != std::string::npos);
  }

  void aBoreCentreIsTheMidpointOfOppositeHitsAndItsDiameterAddsTheTip() {
    Request q{.kind = Kind::Bore, .coordinate_system = 2};
    Routine r(settings(), q, at(100, 50, -10));
    // The first X pair across a chord (the start is off the Y centre), the
    // second across the diameter.
    const Lines l = run(r, {107.5, 94.5, 57, 45, 108.2, 93.8});
    QVERIFY2(!r.failed(), r.error().c_str());
    QCOMPARE(r.result().x, 101.0);
    QCOMPARE(r.result().y, 51.0);
    QCOMPARE(r.result().diameter_x, 108.2 - 93.8 + 2);
    QCOMPARE(r.result().diameter_y, 14.0);  // 57 - 45 + 2
    const std::string all = join(l);
    // X+, back, X-, to the X centre, then Y from there, to the Y centre,
    // then X again from there.
    QVERIFY(all.find("G91 G38.2 X10.0000") < all.find("G53 G0 X100.0000"));
    QVERIFY(all.find("G53 G0 X100.0000") < all.find("G91 G38.2 X-10.0000"));
    QVERIFY(all.find("G91 G38.2 X-10.0000") < all.find("G53 G0 X101.0000"));
    QVERIFY(all.find("G53 G0 X101.0000") < all.find("G91 G38.2 Y10.0000"));
    QVERIFY2(all.find("G53 G0 Y51.0000\nG91 G38.2 X10.0000") != std::string::npos, all.c_str());
    QVERIFY(all.rfind("G91 G38.2 X-10.0000") > all.find("G53 G0 Y51.0000"));
    QCOMPARE(l.at(l.size() - 3), std::string("G10 L2 P2 X101.0000 Y51.0000"));
  }

  void tipCalibrationIsTheGaugeDiameterLessTheCentresTravelBetweenItsWalls() {
    Request q{.kind = Kind::TipCalibration, .gauge_diameter = 20};
    Routine r(settings(), q, at(0, 0, -10));
    // The centre travels 17.02 in X, 17.04 in Y between the walls.
    run(r, {8.4, -8.6, 8.52, -8.52, 8.51, -8.51});
    QVERIFY2(!r.failed(), r.error().c_str());
    QVERIFY(std::fabs(r.result().tip_diameter_x - 2.98) < 1e-9);
    QVERIFY(std::fabs(r.result().tip_diameter_y - 2.96) < 1e-9);
    QVERIFY(std::fabs(r.result().tip_diameter - 2.97) < 1e-9);
    QVERIFY2(r.result().summary.find("tip diameter 2.9700 (X 2.9800, Y 2.9600)") != std::string::npos,
             r.result().summary.c_str());
    QVERIFY_THROWS_EXCEPTION(std::invalid_argument,
                             Routine(settings(), Request{.kind = Kind::TipCalibration}, at(0, 0, 0)));
    // A gauge smaller than the travel: a wrong diameter, not a tip.
    Routine wrong(settings(), Request{.kind = Kind::TipCalibration, .gauge_diameter = 10}, at(0, 0, -10));
    run(wrong, {8.4, -8.6, 8.52, -8.52, 8.51, -8.51});
    QVERIFY(wrong.failed());
    QVERIFY2(wrong.error().find("is the gauge diameter right?") != std::string::npos, wrong.error().c_str());
  }

  void routinesSaveTheModalStateFirstAndRestoreItAtTheEnd() {
    Routine r(settings(), Request{.kind = Kind::Edge, .axis = 0, .direction = 1}, at(0, 0, 0));
    const Lines l = run(r, {20});
    QCOMPARE(l.at(0), std::string("M70"));
    QCOMPARE(l.at(1), std::string("G21 G90 G94"));  // the routine's numbers: machine units per minute, absolute
    QCOMPARE(l.at(l.size() - 2), std::string("M72"));
    QCOMPARE(l.back(), std::string("M71"));
    Settings inch = settings();
    inch.inch = true;
    Routine ri(inch, Request{.kind = Kind::Edge, .axis = 0, .direction = 1}, at(0, 0, 0));
    QCOMPARE(run(ri, {2}).at(1), std::string("G20 G90 G94"));
  }

  void aFailureRestoresTheModalStateTheStatusShowedAtTheStart() {
    Start st = at(0, 0, 0);
    st.gcodes = {10, 180, 910, 911, 950, 200, 400, 490, 980, 550, 640, 970, 80};
    st.feed = 12.5;
    Routine r(settings(), Request{.kind = Kind::Edge, .axis = 0, .direction = 1}, st);
    run(r, {});
    QVERIFY(r.failed());
    QCOMPARE(r.cleanup_lines(), (Lines{"G20 G91 G95 G18", "F12.5000"}));
    st.gcodes = {10, 170, 900, 911, 940, 210};
    st.feed = 0;
    Routine metric(settings(), Request{.kind = Kind::Edge, .axis = 0, .direction = 1}, st);
    QCOMPARE(metric.cleanup_lines(), (Lines{"G21 G90 G94 G17", "F0.0000"}));
  }

  void aBossIsProbedFromOutsideAtDepthAndItsDiameterSubtractsTheTip() {
    Request q{.kind = Kind::Boss, .boss_diameter = 20, .boss_depth = 5};
    Routine r(settings(), q, at(0, 0, 10));
    const Lines l = run(r, {-11, 9, -10.5, 10.5});
    QVERIFY2(!r.failed(), r.error().c_str());
    QCOMPARE(r.result().x, -1.0);
    QCOMPARE(r.result().y, 0.0);
    QCOMPARE(r.result().diameter_x, 18.0);  // (9 - 1) - (-11 + 1)
    QCOMPARE(r.result().diameter_y, 19.0);
    const std::string all = join(l);
    // 20/2 + radius 1 + clearance 4 = 15 out, 5 down, search at most 14 (clearance + search).
    QVERIFY2(all.find("G53 G0 X-15.0000\nG53 G1 Z5.0000 F300.0000\nG91 G38.2 X14.0000") != std::string::npos, all.c_str());
    QVERIFY(all.find("G53 G0 Z10.0000\nG53 G0 X15.0000\nG53 G1 Z5.0000") != std::string::npos);
    QVERIFY(all.find("G53 G0 X-1.0000\nG53 G0 Y-15.0000") != std::string::npos);
  }

  void anInsideCornerProbesBothFacesFromTheStart() {
    Request q{.kind = Kind::InsideCorner, .corner_x = -1, .corner_y = 1, .coordinate_system = 1};
    Routine r(settings(), q, at(30, 40, 0));
    const Lines l = run(r, {22, 45});
    QCOMPARE(r.result().x, 21.0);
    QCOMPARE(r.result().y, 46.0);
    QCOMPARE(l.at(l.size() - 3), std::string("G10 L2 P1 X21.0000 Y46.0000"));
  }

  void anOutsideCornerStepsAlongEachFaceBeforeProbingIt() {
    Request q{.kind = Kind::OutsideCorner, .corner_x = 1, .corner_y = 1, .corner_step = 8};
    Routine r(settings(), q, at(0, 0, 0));
    const Lines l = run(r, {5, 6});
    QCOMPARE(r.result().x, 6.0);
    QCOMPARE(r.result().y, 7.0);
    const std::string all = join(l);
    QVERIFY2(all.rfind("M70\nG21 G90 G94\nG53 G0 Y8.0000\nG91 G38.2 X10.0000", 0) == 0, all.c_str());
    QVERIFY(all.find("G53 G0 Y0.0000\nG53 G0 X0.0000\nG53 G0 X8.0000\nG91 G38.2 Y10.0000") != std::string::npos);
    QVERIFY_THROWS_EXCEPTION(std::invalid_argument,
                             Routine(settings(), Request{.kind = Kind::OutsideCorner, .corner_step = 0}, at(0, 0, 0)));
  }

  void aProbeWithoutContactFailsTheRoutineNamingTheMove() {
    Routine r(settings(), Request{.kind = Kind::Bore}, at(0, 0, 0));
    run(r, {5});  // the second probe finds nothing
    QVERIFY(r.done() && r.failed());
    QCOMPARE(r.error(), std::string("bore centre: probe X-: no contact within the search distance"));
    QCOMPARE(r.cleanup_lines(), Lines{"G90"});  // the start did not give the modal state
  }

  void aRotatedCoordinateSystemRefusesTouchOff() {
    Start st = at(0, 0, 0);
    st.rotation_xy = 30;
    QVERIFY_THROWS_EXCEPTION(std::invalid_argument,
                             Routine(settings(), Request{.kind = Kind::Edge, .coordinate_system = 1}, st));
    Routine ok(settings(), Request{.kind = Kind::Edge}, st);  // measuring only is fine
    QVERIFY(!ok.done());
  }

  void touchOffGoesIntoAnyCoordinateSystem() {
    QCOMPARE(touch_off_line(9, 2, -1.25), std::string("G10 L20 P9 Z-1.2500"));
    QCOMPARE(touch_off_line(2, 0, 0), std::string("G10 L20 P2 X0.0000"));
    QCOMPARE(coordinate_system_name(7), std::string("G59.1"));
    QVERIFY_THROWS_EXCEPTION(std::invalid_argument, touch_off_line(0, 0, 1));
    QVERIFY_THROWS_EXCEPTION(std::invalid_argument, touch_off_line(10, 0, 1));
  }

  void settingsAreReadFromProbeAndErrorsNameTheKey() {
    const auto ini = ini::IniFile::parse(
        "[PROBE]\nTIP_DIAMETER = 3\nSEARCH_DISTANCE = 12\nLATCH_DISTANCE = 0.5\nSEARCH_FEED = 400\nLATCH_FEED = 10\n"
        "SETTER_X = 280\nSETTER_Y = 170\nSETTER_Z = -20\nSETTER_REFERENCE_Z = -110\nSETTER_SEARCH_DISTANCE = 90\n",
        "m.ini");
    const Settings s = Settings::from_ini(ini);
    QCOMPARE(s.tip_radius(), 1.5);
    QVERIFY(s.setter);
    QCOMPARE(s.setter_search_distance, 90.0);
    QCOMPARE(s.setter_safe_z, 0.0);
    const Settings none = Settings::from_ini(ini::IniFile::parse("[EMC]\n", "n.ini"));
    QVERIFY(!none.setter);
    QCOMPARE(none.setter_search_distance, none.search_distance);
    const auto error = [](const std::string& text) {
      try {
        Settings::from_ini(ini::IniFile::parse(text, "bad.ini"));
      } catch (const ConfigError& e) {
        return std::string(e.what());
      }
      return std::string("no error");
    };
    const std::string neg = error("[PROBE]\nTIP_DIAMETER = -1\n");
    QVERIFY2(neg.find("bad.ini:2") != std::string::npos && neg.find("TIP_DIAMETER") != std::string::npos, neg.c_str());
    const std::string latch = error("[PROBE]\nSEARCH_DISTANCE = 2\nLATCH_DISTANCE = 3\n");
    QVERIFY2(latch.find("bad.ini:3") != std::string::npos && latch.find("LATCH_DISTANCE") != std::string::npos, latch.c_str());
    const std::string partial = error("[PROBE]\nSETTER_X = 1\nSETTER_Y = 2\n");
    QVERIFY2(partial.find("SETTER_Z missing") != std::string::npos, partial.c_str());
    const std::string ref = error("[PROBE]\nSETTER_X = 1\nSETTER_Y = 2\nSETTER_Z = -20\nSETTER_REFERENCE_Z = 0\n");
    QVERIFY2(ref.find("bad.ini:5") != std::string::npos && ref.find("SETTER_REFERENCE_Z") != std::string::npos, ref.c_str());
  }
};

QTEST_GUILESS_MAIN(ProbingTests)
#include "probing_tests.moc"
