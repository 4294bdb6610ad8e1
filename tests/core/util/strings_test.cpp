#include <gtest/gtest.h>

#include "core/util/strings.hpp"

using namespace cnc;

TEST(Strings, ParseDoubleIsStrict) {
  EXPECT_EQ(parse_double("1.5"), 1.5);
  EXPECT_EQ(parse_double(" -2e3 "), -2000.0);
  EXPECT_EQ(parse_double("+0.25"), 0.25);
  EXPECT_FALSE(parse_double("1.5mm"));
  EXPECT_FALSE(parse_double(""));
  EXPECT_FALSE(parse_double("inf"));
  EXPECT_FALSE(parse_double("nan"));
}

TEST(Strings, ParseIntAcceptsPrefixes) {
  EXPECT_EQ(parse_int("42"), 42);
  EXPECT_EQ(parse_int("-42"), -42);
  EXPECT_EQ(parse_int("0x1F"), 31);
  EXPECT_EQ(parse_int("0o17"), 15);
  EXPECT_EQ(parse_int("0b101"), 5);
  EXPECT_EQ(parse_int("-9223372036854775808"), INT64_MIN);
  EXPECT_FALSE(parse_int("9223372036854775808"));
  EXPECT_FALSE(parse_int("1.0"));
  EXPECT_FALSE(parse_uint("-1"));
  EXPECT_EQ(parse_uint("18446744073709551615"), UINT64_MAX);
}

TEST(Strings, ParseBoolLinuxCncWords) {
  for (const char* t : {"TRUE", "yes", "On", "1"}) EXPECT_EQ(parse_bool(t), true) << t;
  for (const char* f : {"false", "NO", "off", "0"}) EXPECT_EQ(parse_bool(f), false) << f;
  EXPECT_FALSE(parse_bool("2"));
  EXPECT_FALSE(parse_bool("enabled"));
}

TEST(Strings, SplitAndTrim) {
  EXPECT_EQ(trim("  a b \t"), "a b");
  EXPECT_EQ(split("a,,b", ','), (std::vector<std::string>{"a", "", "b"}));
  EXPECT_EQ(split("a,,b", ',', true), (std::vector<std::string>{"a", "b"}));
  EXPECT_EQ(split_blanks("  net  x\ty "), (std::vector<std::string>{"net", "x", "y"}));
}

TEST(Strings, FormatDoubleRoundTrips) {
  for (double v : {0.1, 1.0 / 3.0, 1e-300, 123456.789, -0.0}) {
    EXPECT_EQ(*parse_double(format_double(v)), v);
  }
  EXPECT_EQ(format_double(0.5), "0.5");
}
