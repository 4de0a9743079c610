// SPDX-License-Identifier: Apache-2.0
#include "thinslab/app/option_parser.h"

#include <gtest/gtest.h>

#include <string>
#include <vector>

#include "thinslab/core/file.h"
#include "thinslab/core/provenance.h"
#include "tests/testing/temp_dir.h"

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

// A diagnostic option is written as a comment, and the digest reads no comment line.
TEST(OptionParser, DiagnosticOptionsAreCommentsOutsideTheDigest) {
  OptionParser parser("fit test");
  double x = 1;
  std::string pixel;
  parser.AddDouble("x", &x, "");
  parser.AddString("pixel", &pixel, "");
  parser.MarkDiagnostic("pixel");
  ASSERT_TRUE(ParseArgs(&parser, {"--x", "2"}).ok());
  const std::string plain = parser.ToIni();
  ASSERT_TRUE(ParseArgs(&parser, {"--x", "2", "--pixel", "3,4"}).ok());
  const std::string traced = parser.ToIni();
  EXPECT_NE(traced.find("# pixel = 3,4"), std::string::npos) << traced;
  EXPECT_NE(plain, traced);
  EXPECT_EQ(OptionsDigest(plain), OptionsDigest(traced));
  ASSERT_TRUE(ParseArgs(&parser, {"--x", "3"}).ok());
  EXPECT_NE(OptionsDigest(parser.ToIni()), OptionsDigest(plain));
  EXPECT_EQ(OptionsDigest("# any header\nx = 2\n"), OptionsDigest("x = 2\n"));
  EXPECT_EQ(OptionsDigest("x = 2\n"), "fnv1a64:" + Digest("x = 2\n"));
}

// --config FILE: an options.ini written by ToIni() repeats the run; the command line overrides it.
TEST(OptionParser, ConfigRepeatsARunAndTheCommandLineOverridesIt) {
  TempDir dir;
  std::string capture, out;
  double albedo = 0.3, pitch = 1e-4;
  int threads = 2;
  bool refine = true;
  auto make = [&](OptionParser* p) {
    p->AddPositional("CAPTURE", &capture, "");
    p->AddString("out", &out, "");
    p->AddDouble("albedo", &albedo, "");
    p->AddDouble("pitch", &pitch, "");
    p->AddInt("threads", &threads, "");
    p->AddBool("refine", &refine, "");
  };
  OptionParser first("fit tau");
  make(&first);
  ASSERT_TRUE(ParseArgs(&first, {"cap", "--albedo", "0.123456789012345678", "--pitch", "3.3e-05", "--refine",
                                 "false", "--out", "x/y"})
                  .ok());
  const std::string ini = first.ToIni();
  const double albedo_given = albedo, pitch_given = pitch;
  const std::string path = dir / "options.ini";
  ASSERT_TRUE(WriteFileAtomically(path, ini).ok());

  capture = out = "";
  albedo = 0.3, pitch = 1e-4, refine = true;
  OptionParser again("fit tau");
  make(&again);
  ASSERT_TRUE(ParseArgs(&again, {"--config", path}).ok());
  EXPECT_EQ(capture, "cap");
  EXPECT_EQ(out, "x/y");
  EXPECT_EQ(albedo, albedo_given);  // Bit for bit: doubles are written to round-trip.
  EXPECT_EQ(pitch, pitch_given);
  EXPECT_FALSE(refine);
  EXPECT_EQ(again.ToIni(), ini);
  EXPECT_FALSE(again.IsSet("albedo"));  // Set by the file, not the command line.

  OptionParser overridden("fit tau");
  make(&overridden);
  ASSERT_TRUE(ParseArgs(&overridden, {"other", "--threads", "1", "--config=" + path}).ok());
  EXPECT_EQ(capture, "other");
  EXPECT_EQ(threads, 1);
  EXPECT_EQ(albedo, albedo_given);
  EXPECT_TRUE(overridden.IsSet("threads"));
}

TEST(OptionParser, ConfigErrorsNameTheFileLineAndOption) {
  TempDir dir;
  std::string capture;
  double albedo = 0.3;
  OptionParser parser("fit tau");
  parser.AddPositional("CAPTURE", &capture, "");
  parser.AddDouble("albedo", &albedo, "");
  const std::string path = dir / "options.ini";
  auto error = [&](const std::string& text) {
    EXPECT_TRUE(WriteFileAtomically(path, text).ok());
    const Status s = ParseArgs(&parser, {"--config", path});
    EXPECT_FALSE(s.ok()) << text;
    return s.message();
  };
  EXPECT_NE(error("# thinslab fit tau: effective options\nalbedo = half\n").find(path + " line 2: albedo = 'half' is not a valid number"),
            std::string::npos);
  EXPECT_NE(error("CAPTURE = c\nsmoothness = 1\n").find("line 2: 'smoothness' is not an option of thinslab fit tau"),
            std::string::npos);
  EXPECT_NE(error("# thinslab fit dmf: effective options\n").find("written by `thinslab fit dmf`, not `thinslab fit tau`"),
            std::string::npos);
  EXPECT_NE(error("albedo 0.3\n").find("line 1: expected 'name = value'"), std::string::npos);
  const Status missing = ParseArgs(&parser, {"--config", dir / "none.ini"});
  ASSERT_FALSE(missing.ok());
  EXPECT_NE(missing.message().find("none.ini"), std::string::npos);
  // A config without the positional leaves it missing.
  EXPECT_NE(error("albedo = 0.2\n").find("missing argument CAPTURE"), std::string::npos);
}

// What CLI11 now parses: negative numbers as values, `-o` for `--out`, the bare arguments after
// the positionals as a list (calib camera IMAGES...), an unknown option named before a missing
// positional, and --help with the usage line, the footer and the common options.
TEST(OptionParser, Cli11ParsesValuesListsShortNamesAndHelp) {
  OptionParser parser("calib camera");
  double g = 0;
  std::string out;
  std::vector<std::string> images;
  parser.AddPositionalList("IMAGES", &images, "photographs");
  parser.AddDouble("g", &g, "anisotropy");
  parser.AddString("out", &out, "output folder");
  parser.SetShortName("out", 'o');
  parser.SetUsageLine("usage: thinslab calib camera IMAGES... | --images DIR [options]");
  parser.SetHelpFooter("Exit status: 0.");
  ASSERT_TRUE(ParseArgs(&parser, {"a.png", "--g", "-0.5", "b.png", "-o", "dir", "c.png"}).ok());
  EXPECT_EQ(g, -0.5);
  EXPECT_EQ(out, "dir");
  EXPECT_EQ(images, (std::vector<std::string>{"a.png", "b.png", "c.png"}));
  EXPECT_NE(parser.ToIni().find("IMAGES = a.png,b.png,c.png"), std::string::npos) << parser.ToIni();

  ASSERT_TRUE(ParseArgs(&parser, {"--help"}).ok());
  EXPECT_TRUE(parser.help_requested());
  const std::string usage = parser.Usage();
  for (const char* part : {"usage: thinslab calib camera IMAGES... | --images DIR [options]", "--g", "-o", "--out",
                           "--config", "--quiet", "--verbose", "Exit status: 0."}) {
    EXPECT_NE(usage.find(part), std::string::npos) << part << " not in\n" << usage;
  }

  OptionParser fit("fit tau");
  std::string capture;
  fit.AddPositional("CAPTURE", &capture, "");
  fit.AddDouble("albedo", &g, "");
  const Status unknown = ParseArgs(&fit, {"--albdo", "0.3"});
  ASSERT_FALSE(unknown.ok());
  EXPECT_NE(unknown.message().find("unknown option --albdo"), std::string::npos) << unknown.message();
  const Status missing = ParseArgs(&fit, {"--albedo", "0.3"});
  EXPECT_NE(missing.message().find("missing argument CAPTURE"), std::string::npos) << missing.message();
  const Status extra = ParseArgs(&fit, {"cap", "other"});
  EXPECT_NE(extra.message().find("unexpected argument 'other'"), std::string::npos) << extra.message();
  const Status bad_flag = ParseArgs(&fit, {"cap", "--quiet=maybe"});
  EXPECT_NE(bad_flag.message().find("--quiet = 'maybe' is not a valid true/false"), std::string::npos)
      << bad_flag.message();
}

// PeekValue reads one option before the full parse (acquire's --camera), from the command line
// or from the --config file, whatever else the arguments hold.
TEST(OptionParser, PeekValueSeesTheCommandLineAndTheConfigFile) {
  TempDir dir;
  auto peek = [](std::vector<std::string> args) {
    std::vector<char*> argv;
    for (auto& a : args) argv.push_back(a.data());
    std::string camera = "sim";
    EXPECT_TRUE(
        OptionParser::PeekValue("acquire laser", static_cast<int>(argv.size()), argv.data(), "camera", &camera).ok());
    return camera;
  };
  EXPECT_EQ(peek({"out", "--photons", "100", "--resume", "--verbose"}), "sim");
  EXPECT_EQ(peek({"--camera=aravis:127.0.0.1", "out"}), "aravis:127.0.0.1");
  EXPECT_EQ(peek({"--resume", "out", "--camera", "v4l2:/dev/video0", "--help"}), "v4l2:/dev/video0");
  const std::string ini = dir / "options.ini";
  ASSERT_TRUE(WriteFileAtomically(ini,
                                  "# thinslab acquire laser: effective options\nOUTPUT = s\ncamera = aravis:10.0.0.2\n"
                                  "gain-db = 3\n")
                  .ok());
  EXPECT_EQ(peek({"--config", ini}), "aravis:10.0.0.2");
  EXPECT_EQ(peek({"--config", ini, "--camera", "sim"}), "sim");  // The command line overrides the file.
}

}  // namespace
}  // namespace thinslab
