#include <gtest/gtest.h>

#include <string>

#include "core/error.hpp"

namespace scout {
namespace {

TEST(FirstLine, KeepsALibrarysFirstLineWithoutC10dsPrefixClippedAndEscaped) {
  EXPECT_EQ(first_line("PytorchStreamReader failed\nException raised from ... (backtrace)"),
            "PytorchStreamReader failed");
  EXPECT_EQ(first_line("[/build/gloo/transport/tcp/pair.cc:598] Connection closed by peer"),
            "Connection closed by peer");
  EXPECT_EQ(first_line("[not a prefix"), "[not a prefix");
  EXPECT_EQ(first_line(std::string(300, 'x')), std::string(200, 'x'));
  EXPECT_EQ(first_line("tab\there\r"), "tab\\there\\r");
  EXPECT_EQ(first_line(""), "");
}

}  // namespace
}  // namespace scout
