// Exports for other controls, read back: LinuxCNC (parses as a COMP_FILE,
// <= 256 entries, trims undo the error), Siemens LEC (one value per point,
// step/min/max consistent, sign = error, 0 at the reference), Heidenhain
// .COM (table framing, both directions), Fanuc (the incremental data sum
// up to the corrections, 0 at the reference moving +, the reversal there in
// 3627; parameters consistent).
#include <gtest/gtest.h>

#include <cmath>
#include <map>
#include <regex>
#include <sstream>

#include "comp/comp_table.hpp"
#include "comp/exports.hpp"

using namespace cnc::comp;

namespace {

ErrorModel model() {
  ErrorModel m;
  m.x_min = 0;
  m.x_max = 400;
  m.spline = {2, 4, 9, 7, 12, 15, 13};
  m.backlash0_um = 7;
  m.backlash1_um = -2;
  m.lead_mm = 10;
  m.sin_um = {0.8};
  m.cos_um = {0.3};
  return m;
}

// Error relative to the mean at the reference, as the exports use it.
double error_um(const ErrorModel& m, double x, int d, double ref) {
  return m.deviation_um(x, d) - (m.deviation_um(ref, 1) + m.deviation_um(ref, -1)) / 2;
}

std::vector<std::string> lines(const std::string& s) {
  std::vector<std::string> out;
  std::istringstream in(s);
  for (std::string l; std::getline(in, l);) out.push_back(l);
  return out;
}

}  // namespace

TEST(Exports, LinuxCncReadsBackWithinTheStatedInterpolationError) {
  const ErrorModel m = model();
  ExportOptions o;
  for (int type : {0, 1}) {
    const std::string text = export_linuxcnc(m, o, type);
    const CompTable t = parse_comp_table(text, static_cast<CompFileType>(type), "export");
    EXPECT_LE(t.size(), 256u);
    EXPECT_GE(t.size(), 100u);
    std::smatch match;
    ASSERT_TRUE(std::regex_search(text, match, std::regex("within ([0-9.]+) um of the model")));
    const double stated = std::stod(match[1]);
    for (double x = 0; x <= 400; x += 0.37) {
      EXPECT_NEAR(-t.forward_at(x) * 1000, error_um(m, x, 1, 0), stated + 1e-3) << x;
      EXPECT_NEAR(-t.reverse_at(x) * 1000, error_um(m, x, -1, 0), stated + 1e-3) << x;
    }
  }
}

TEST(Exports, SiemensLecTableIsConsistent) {
  const ErrorModel m = model();
  ExportOptions o;
  o.axis = "X1";
  o.reference_mm = 100;
  const std::string text = export_siemens_lec(m, o);
  const auto ls = lines(text);
  ASSERT_EQ(ls.front(), "%_N_AX_EEC_INI");
  EXPECT_EQ(ls.back(), "M17");
  std::map<int, double> values;
  double step = 0, min = 0, max = 0;
  const std::regex value(R"(\$AA_ENC_COMP\[0,(\d+),X1\]=(-?[0-9.]+))");
  for (const auto& l : ls) {
    std::smatch mt;
    if (std::regex_match(l, mt, value)) values[std::stoi(mt[1])] = std::stod(mt[2]);
    if (l.rfind("$AA_ENC_COMP_STEP[0,X1]=", 0) == 0) step = std::stod(l.substr(24));
    if (l.rfind("$AA_ENC_COMP_MIN[0,X1]=", 0) == 0) min = std::stod(l.substr(23));
    if (l.rfind("$AA_ENC_COMP_MAX[0,X1]=", 0) == 0) max = std::stod(l.substr(23));
  }
  ASSERT_GT(step, 0);
  EXPECT_LE(values.size(), 200u) << "fits the 200 points of the smaller controls by default";
  EXPECT_EQ(static_cast<int>(values.size()), static_cast<int>(std::lround((max - min) / step)) + 1);
  EXPECT_EQ(values.begin()->first, 0);
  EXPECT_GE(max, 400);
  for (const auto& [i, v] : values) {
    const double x = min + i * step;
    const double mean_error = (error_um(m, x, 1, 100) + error_um(m, x, -1, 100)) / 2;
    EXPECT_NEAR(v * 1000, mean_error, 1e-3) << "positive value = positive error (the axis is moved back)";
  }
  EXPECT_NE(text.find("MD32450 $MA_BACKLASH[0] = 0.00700"), std::string::npos);
}

TEST(Exports, HeidenhainComTable) {
  const ErrorModel m = model();
  ExportOptions o;
  o.axis = "Z";
  const auto ls = lines(export_heidenhain_com(m, o));
  ASSERT_GE(ls.size(), 4u);
  EXPECT_EQ(ls[0], "BEGIN Z.COM MM");
  EXPECT_EQ(ls.back(), "[END]");
  std::istringstream head(ls[1]);
  std::string a, b, c, d;
  head >> a >> b >> c >> d;
  EXPECT_EQ(a + " " + b + " " + c + " " + d, "NR AXISPOS Z BACKLASH");
  for (std::size_t i = 2; i + 1 < ls.size(); ++i) {
    std::istringstream row(ls[i]);
    int nr;
    double x, plus, minus;
    row >> nr >> x >> plus >> minus;
    EXPECT_EQ(nr, static_cast<int>(i - 2));
    EXPECT_NEAR(plus * 1000, -error_um(m, x, 1, 0), 0.006);
    EXPECT_NEAR(minus * 1000, -error_um(m, x, -1, 0), 0.006);
  }
  EXPECT_LE(ls.size() - 3, 256u);
}

TEST(Exports, FanucIncrementsSumToTheCorrections) {
  const ErrorModel m = model();
  ExportOptions o;
  o.reference_mm = 150;
  o.fanuc_reference_point = 200;
  o.fanuc_magnification = 1;
  o.fanuc_unit_um = 1;
  const std::string text = export_fanuc_pitch(m, o);
  std::map<int, long> params;
  std::map<int, long> data;
  double interval = 0;
  for (const auto& l : lines(text)) {
    std::smatch mt;
    if (std::regex_match(l, mt, std::regex(R"(N(\d{5})A1P(-?[0-9.]+))"))) {
      if (std::stoi(mt[1]) == 3624) interval = std::stod(mt[2]);
      else params[std::stoi(mt[1])] = std::stol(mt[2]);
    } else if (std::regex_match(l, mt, std::regex(R"(N(\d{5})P(-?\d+))"))) {
      data[std::stoi(mt[1]) - 10000] = std::stol(mt[2]);
    }
  }
  ASSERT_GT(interval, 0);
  EXPECT_EQ(params[3620], 200);
  EXPECT_EQ(params[3605], 1) << "bidirectional pitch error compensation";
  const int kmin = static_cast<int>(params[3621]), kmax = static_cast<int>(params[3622]);
  EXPECT_LE(kmax - kmin + 1, 129) << "at most 128 intervals by default";
  EXPECT_LE(150 - (200 - kmin) * interval, 0 + 1e-9) << "covers x_min";
  EXPECT_GE(150 + (kmax - 200) * interval, 400 - 1e-9) << "covers x_max";
  // Forward table: running sums from the reference give the corrections.
  for (const int d : {1, -1}) {
    const int base = d > 0 ? kmin : static_cast<int>(params[3626]);
    long sum_at_ref = 0, sum = 0;
    std::map<int, long> absolute;
    for (int k = kmin; k <= kmax; ++k) {
      ASSERT_TRUE(data.count(base + k - kmin)) << "point " << k;
      sum += data[base + k - kmin];
      absolute[k] = sum;
      if (k == 200) sum_at_ref = sum;
    }
    const long ref_offset = d > 0 ? 0 : params[3627];
    for (int k = kmin; k <= kmax; ++k) {
      const double x = 150 + (k - 200) * interval;
      const double want = -(m.deviation_um(x, d) - m.deviation_um(150, 1));  // 0 at the reference moving +
      EXPECT_NEAR(static_cast<double>(absolute[k] - sum_at_ref + ref_offset), want, 0.5 + 1e-9) << "point " << k;
    }
  }
}

namespace {

struct FanucTape {
  std::map<int, std::map<int, double>> params;  // parameter -> axis -> value
  std::map<int, long> data;                      // point -> increment
};

FanucTape read_fanuc(const std::string& text) {
  FanucTape t;
  for (const auto& l : lines(text)) {
    std::smatch mt;
    if (std::regex_match(l, mt, std::regex(R"(N(\d{5})A(\d+)P(-?[0-9.]+))"))) {
      t.params[std::stoi(mt[1])][std::stoi(mt[2])] = std::stod(mt[3]);
    } else if (std::regex_match(l, mt, std::regex(R"(N(\d{5})P(-?\d+))"))) {
      t.data[std::stoi(mt[1]) - 10000] = std::stol(mt[2]);
    }
  }
  return t;
}

}  // namespace

// The tape used to name axis 1 and reference point 100 for every axis: a
// Y tape loaded after X's overwrote X's parameters and compensation data.
TEST(Exports, FanucTapesOfDifferentAxesUseTheirOwnAxisNumberAndPoints) {
  const ErrorModel m = model();
  std::map<std::string, FanucTape> tapes;
  std::map<std::string, FanucPoints> used;
  for (const char* axis : {"X", "Y", "Z"}) {
    ExportOptions o;
    o.axis = axis;
    tapes[axis] = read_fanuc(export_fanuc_pitch(m, o, &used[axis]));
  }
  EXPECT_EQ(used["X"].axis, 1);
  EXPECT_EQ(used["Y"].axis, 2);
  EXPECT_EQ(used["Z"].axis, 3);
  for (const auto& [axis, tape] : tapes) {
    for (const auto& [param, by_axis] : tape.params) {
      ASSERT_EQ(by_axis.size(), 1u) << axis << " " << param;
      EXPECT_EQ(by_axis.begin()->first, used[axis].axis) << axis << " parameter " << param;
    }
    EXPECT_EQ(tape.params.at(3620).begin()->second, used[axis].reference);
    EXPECT_EQ(tape.data.begin()->first, used[axis].first);
    EXPECT_EQ(tape.data.rbegin()->first, used[axis].neg_last);
  }
  for (const char* a : {"X", "Y"}) {
    for (const char* b : {"Y", "Z"}) {
      if (std::string(a) == b) continue;
      for (const auto& [point, inc] : tapes[a].data) EXPECT_EQ(tapes[b].data.count(point), 0u) << a << b << point;
    }
  }
  EXPECT_GE(used["Y"].first, kFanucPointsPerAxis);
  EXPECT_LT(used["Y"].neg_last, 2 * kFanucPointsPerAxis);
}

TEST(Exports, FanucRefusesAnUnknownAxisNumberOrAReferencePointWithoutRoom) {
  const ErrorModel m = model();
  ExportOptions o;
  o.axis = "A";
  try {
    export_fanuc_pitch(m, o);
    FAIL() << "no error";
  } catch (const std::invalid_argument& e) {
    EXPECT_NE(std::string(e.what()).find("controlled-axis number of axis A is not known; give it (cnc-comp --fanuc-axis N"),
              std::string::npos)
        << e.what();
  }
  o.fanuc_axis = 4;
  FanucPoints used;
  EXPECT_NE(export_fanuc_pitch(m, o, &used).find("N03620A4P"), std::string::npos);
  EXPECT_EQ(used.first, 3 * kFanucPointsPerAxis);
  o.reference_mm = 150;
  o.fanuc_reference_point = 10;
  EXPECT_THROW(export_fanuc_pitch(m, o), std::invalid_argument) << "points below the reference need numbers below it";
  o.fanuc_reference_point = 600;
  o.fanuc_magnification = 0;
  EXPECT_THROW(export_fanuc_pitch(m, o), std::invalid_argument);
  o.fanuc_magnification = 1;
  o.fanuc_unit_um = 0;
  EXPECT_THROW(export_fanuc_pitch(m, o), std::invalid_argument);
}

TEST(Exports, FanucDataAreInDetectionUnitsTimesTheMagnification) {
  const ErrorModel m = model();
  ExportOptions o;
  o.reference_mm = 150;
  o.fanuc_bidirectional = false;
  const FanucTape unit = read_fanuc(export_fanuc_pitch(m, o));
  o.fanuc_unit_um = 0.1;
  o.fanuc_magnification = 2;
  const FanucTape fine = read_fanuc(export_fanuc_pitch(m, o));
  EXPECT_EQ(fine.params.at(3623).at(1), 2);
  EXPECT_EQ(fine.params.count(3605), 0u) << "unidirectional";
  long sum_unit = 0, sum_fine = 0;
  long worst = 0;
  for (const auto& [point, inc] : unit.data) {
    sum_unit += inc;
    sum_fine += fine.data.at(point);
    worst = std::max(worst, std::labs(sum_fine - 5 * sum_unit));
  }
  EXPECT_LE(worst, 3) << "0.2 um per count: five times the counts of 1 um (within rounding)";
  EXPECT_GT(std::labs(sum_fine), 0);
}
