#include <gtest/gtest.h>

#include <fstream>

#include "core/digest.hpp"
#include "core/error.hpp"
#include "tests/support/temp_dir.hpp"

namespace scout::core {
namespace {

TEST(Digest, HexAndSha256MatchTheStandardsExamples) {
  const std::uint8_t bytes[] = {0x00, 0x0f, 0xa0, 0xff};
  EXPECT_EQ(to_hex(bytes), "000fa0ff");
  EXPECT_EQ(to_hex({}), "");
  scout::testing::TempDir temp;
  std::ofstream(temp.path() / "abc") << "abc";
  // FIPS 180-2, appendix B.1.
  EXPECT_EQ(sha256_hex(temp.path() / "abc"), "ba7816bf8f01cfea414140de5dae2223b00361a396177a9cb410ff61f20015ad");
  EXPECT_THROW(sha256_hex(temp.path() / "missing"), InputError);
}

}  // namespace
}  // namespace scout::core
