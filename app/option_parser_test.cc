// SPDX-License-Identifier: Apache-2.0
#include "thinslab/app/option_parser.h"

#include <gtest/gtest.h>

#include <string>
#include <vector>

namespace thinslab {
namespace {

Status ParseArgs(OptionParser* parser, std::vector<std::string> args) {
  std::vector<char*> argv;
  for (auto& a : args) argv.push_back(a.data());
  return parser->Parse(static_cast<int>(argv.size()), argv.data());
}

TEST(OptionParser, FlagBeforeAPositionalDoesNotSwallowIt) {
  OptionParser parser("test");
  bool resume = false;
  std::string out;
  double x = 0;
  parser.AddBool("resume", &resume, "");
  parser.AddDouble("x", &x, "");
  parser.AddPositional("OUTPUT", &out, "");
  ASSERT_TRUE(ParseArgs(&parser, {"--resume", "/tmp/session", "--x", "2.5"}).ok());
  EXPECT_TRUE(resume);
  EXPECT_EQ(out, "/tmp/session");
  EXPECT_EQ(x, 2.5);
  EXPECT_TRUE(parser.IsSet("resume"));
  EXPECT_TRUE(parser.IsSet("x"));
  ASSERT_TRUE(ParseArgs(&parser, {"/tmp/other"}).ok());
  EXPECT_FALSE(parser.IsSet("x"));  // Defaults and earlier parses do not count.
}

TEST(OptionParser, FlagTakesAnExplicitBooleanWord) {
  OptionParser parser("test");
  bool a = true, b = false;
  std::string out;
  parser.AddBool("a", &a, "");
  parser.AddBool("b", &b, "");
  parser.AddPositional("OUTPUT", &out, "");
  ASSERT_TRUE(ParseArgs(&parser, {"--a", "false", "--b=yes", "dir"}).ok());
  EXPECT_FALSE(a);
  EXPECT_TRUE(b);
  EXPECT_EQ(out, "dir");
}

TEST(OptionParser, BadValuesNameTheOption) {
  OptionParser parser("test");
  bool a = false;
  double x = 0;
  parser.AddBool("a", &a, "");
  parser.AddDouble("x", &x, "");
  Status status = ParseArgs(&parser, {"--a=maybe"});
  ASSERT_FALSE(status.ok());
  EXPECT_NE(status.message().find("--a"), std::string::npos);
  status = ParseArgs(&parser, {"--x"});
  ASSERT_FALSE(status.ok());
  EXPECT_NE(status.message().find("--x needs a value"), std::string::npos);
}

// docs/format.md promises standard 64-bit FNV-1a: the published test vectors.
TEST(DigestTest, IsStandardFnv1a64) {
  EXPECT_EQ(Digest(""), "cbf29ce484222325");
  EXPECT_EQ(Digest("a"), "af63dc4c8601ec8c");
  EXPECT_EQ(Digest("foobar"), "85944171f73967e8");
}

}  // namespace
}  // namespace thinslab
