// util::quoteInput, oneLineMessage and getBoundedLine.
#include "libwheelchair/util/Text.h"

#include <gtest/gtest.h>

#include <sstream>

using namespace wheelchair::util;

TEST(QuoteInput, EscapesControlAndNonAsciiBytesAndCuts) {
  EXPECT_EQ(quoteInput("a\tb\r\n\x1b[2J\x7f\xc3"), "a\\tb\\r\\n\\x1b[2J\\x7f\\xc3");
  EXPECT_EQ(quoteInput(std::string(100, 'a'), 10), std::string(10, 'a') + "...");
  EXPECT_EQ(quoteInput("short", 10), "short");
}

TEST(OneLineMessage, InnermostMrptMessageOrFirstLine) {
  const std::string nested =
      "==== MRPT exception ====\nMessage:  Exception while parsing typed object 'x'.\n"
      "Original exception:\n==== MRPT exception ====\nMessage:  Expecting 0x00 00 00\n"
      "Location: CArchive.cpp:364\nCall stack backtrace:\n[0 ] foo\n";
  EXPECT_EQ(oneLineMessage(nested), "Expecting 0x00 00 00");
  EXPECT_EQ(oneLineMessage("\n  plain error\nsecond line"), "plain error");
}

TEST(GetBoundedLine, ReadsLinesAndRefusesALongOne) {
  std::istringstream in("ab\n\ncd");
  std::string line;
  ASSERT_TRUE(getBoundedLine(in, line, 10, "f", 1));
  EXPECT_EQ(line, "ab");
  ASSERT_TRUE(getBoundedLine(in, line, 10, "f", 2));
  EXPECT_EQ(line, "");
  ASSERT_TRUE(getBoundedLine(in, line, 10, "f", 3));
  EXPECT_EQ(line, "cd");
  EXPECT_FALSE(getBoundedLine(in, line, 10, "f", 4));
  std::istringstream big(std::string(100, 'x'));
  try {
    getBoundedLine(big, line, 10, "data.csv", 7);
    FAIL() << "no exception";
  } catch (const std::runtime_error& e) {
    EXPECT_STREQ(e.what(), "data.csv:7: line longer than 10 bytes (no newline?)");
  }
}
