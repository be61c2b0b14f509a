// Command-line parsing (services/common/cli.h): every type, both `--name value` and
// `--name=value`, one-line errors with exit status 2, --help with exit status 0.
#include <gtest/gtest.h>
#include <unistd.h>

#include <initializer_list>
#include <stdexcept>
#include <string>
#include <vector>

#include "common/cli.h"

namespace godhand {
namespace {

/// argv for Cli::parse: {"prog", args...}.
class Args {
 public:
  Args(std::initializer_list<std::string> args) : strings_{"prog"} {
    strings_.insert(strings_.end(), args);
    for (std::string& s : strings_) ptrs_.push_back(s.data());
    ptrs_.push_back(nullptr);
  }
  int argc() const { return static_cast<int>(strings_.size()); }
  char** argv() { return ptrs_.data(); }

 private:
  std::vector<std::string> strings_;
  std::vector<char*> ptrs_;
};

/// Every option type, with defaults.
struct Options {
  std::string lab = "deploy/lab/local.pbtxt";
  std::string out;
  int frames = 100;
  double rate = 90.0;
  bool quiet = false;
  std::vector<std::string> meshes;

  explicit Options(Cli& cli) {
    cli.option("lab", &lab, "FILE", "lab configuration");
    cli.option("out", &out, "FILE", "where to write");
    cli.option("frames", &frames, "N", "how many frames");
    cli.option("--rate", &rate, "HZ", "loop rate");  // a leading "--" is accepted
    cli.flag("quiet", &quiet, "no progress lines");
    cli.multi("mesh", &meshes, "FILE", "a mesh");
  }
};

/// Regex matching exactly `text` (POSIX extended, as gtest uses on Linux).
std::string exactly(const std::string& text) {
  std::string re = "^";
  for (char c : text) {
    if (std::string("\\^$.|?*+()[]{}").find(c) != std::string::npos) re += '\\';
    re += c;
  }
  return re + "$";
}

/// The stderr of a bad command line: exactly one line plus the hint.
std::string oneLineError(const std::string& reason) { return exactly("prog: " + reason + "\ntry prog --help\n"); }

void parseOrDie(std::initializer_list<std::string> args) {
  Cli cli("prog", "A test program.");
  Options o(cli);
  Args a(args);
  cli.parse(a.argc(), a.argv());
  std::exit(0);  // parsed: not what the death tests below expect
}

TEST(Cli, DefaultsKeptWhenNotGiven) {
  Cli cli("prog", "");
  Options o(cli);
  Args a({});
  cli.parse(a.argc(), a.argv());
  EXPECT_EQ(o.lab, "deploy/lab/local.pbtxt");
  EXPECT_EQ(o.out, "");
  EXPECT_EQ(o.frames, 100);
  EXPECT_EQ(o.rate, 90.0);
  EXPECT_FALSE(o.quiet);
  EXPECT_TRUE(o.meshes.empty());
}

TEST(Cli, ParsesEveryTypeSeparateValue) {
  Cli cli("prog", "");
  Options o(cli);
  Args a({"--lab", "a.pbtxt", "--frames", "-7", "--rate", "-2.5e1", "--quiet", "--mesh", "x.obj", "--out", "o.txt", "--mesh", "y.obj"});
  cli.parse(a.argc(), a.argv());
  EXPECT_EQ(o.lab, "a.pbtxt");
  EXPECT_EQ(o.out, "o.txt");
  EXPECT_EQ(o.frames, -7);
  EXPECT_EQ(o.rate, -25.0);
  EXPECT_TRUE(o.quiet);
  EXPECT_EQ(o.meshes, (std::vector<std::string>{"x.obj", "y.obj"}));
}

TEST(Cli, ParsesEveryTypeEqualsForm) {
  Cli cli("prog", "");
  Options o(cli);
  Args a({"--lab=b.pbtxt", "--frames=+12", "--rate=0.125", "--mesh=z.obj", "--out=--odd=name", "--mesh=with space.obj"});
  cli.parse(a.argc(), a.argv());
  EXPECT_EQ(o.lab, "b.pbtxt");
  EXPECT_EQ(o.out, "--odd=name");  // everything after the first '='
  EXPECT_EQ(o.frames, 12);
  EXPECT_EQ(o.rate, 0.125);
  EXPECT_FALSE(o.quiet);
  EXPECT_EQ(o.meshes, (std::vector<std::string>{"z.obj", "with space.obj"}));
}

TEST(Cli, LastValueWins) {
  Cli cli("prog", "");
  Options o(cli);
  Args a({"--frames", "1", "--frames=2", "--lab", "x", "--lab", "y"});
  cli.parse(a.argc(), a.argv());
  EXPECT_EQ(o.frames, 2);
  EXPECT_EQ(o.lab, "y");
}

TEST(Cli, IntegerLimits) {
  Cli cli("prog", "");
  Options o(cli);
  Args a({"--frames", "2147483647"});
  cli.parse(a.argc(), a.argv());
  EXPECT_EQ(o.frames, 2147483647);
}

TEST(CliDeathTest, UnknownOption) {
  EXPECT_EXIT(parseOrDie({"--bogus"}), ::testing::ExitedWithCode(2), oneLineError("unknown option '--bogus'"));
  EXPECT_EXIT(parseOrDie({"--bogus=3"}), ::testing::ExitedWithCode(2), oneLineError("unknown option '--bogus'"));
  EXPECT_EXIT(parseOrDie({"-q"}), ::testing::ExitedWithCode(2), oneLineError("unknown option '-q'"));
}

TEST(CliDeathTest, PositionalJunk) {
  EXPECT_EXIT(parseOrDie({"--quiet", "junk"}), ::testing::ExitedWithCode(2),
              oneLineError("unexpected argument 'junk' (options start with --)"));
  EXPECT_EXIT(parseOrDie({"--"}), ::testing::ExitedWithCode(2),
              oneLineError("unexpected argument '--' (this program takes no positional arguments)"));
  EXPECT_EXIT(parseOrDie({""}), ::testing::ExitedWithCode(2), oneLineError("unexpected argument '' (options start with --)"));
}

TEST(CliDeathTest, MissingValue) {
  EXPECT_EXIT(parseOrDie({"--lab"}), ::testing::ExitedWithCode(2), oneLineError("--lab: missing value (--lab FILE)"));
  EXPECT_EXIT(parseOrDie({"--rate", "--quiet"}), ::testing::ExitedWithCode(2),
              oneLineError("--rate: missing value (--rate HZ), got option '--quiet'"));
}

TEST(CliDeathTest, EmptyStringValues) {
  // `--partition "$UNSET"` must not silently mean "no partition", nor `--json ''` "no report".
  EXPECT_EXIT(parseOrDie({"--lab", ""}), ::testing::ExitedWithCode(2),
              oneLineError("--lab: empty value (leave the option out for its default)"));
  EXPECT_EXIT(parseOrDie({"--out="}), ::testing::ExitedWithCode(2),
              oneLineError("--out: empty value (leave the option out for its default)"));
  EXPECT_EXIT(parseOrDie({"--mesh", "a.obj", "--mesh", ""}), ::testing::ExitedWithCode(2), oneLineError("--mesh: empty value"));
}

TEST(CliDeathTest, FlagTakesNoValue) {
  EXPECT_EXIT(parseOrDie({"--quiet=yes"}), ::testing::ExitedWithCode(2), oneLineError("--quiet takes no value, got '--quiet=yes'"));
}

TEST(CliDeathTest, BadIntegers) {
  EXPECT_EXIT(parseOrDie({"--frames", "abc"}), ::testing::ExitedWithCode(2), oneLineError("--frames: expected an integer, got 'abc'"));
  EXPECT_EXIT(parseOrDie({"--frames=12x"}), ::testing::ExitedWithCode(2), oneLineError("--frames: expected an integer, got '12x'"));
  EXPECT_EXIT(parseOrDie({"--frames", "1.5"}), ::testing::ExitedWithCode(2), oneLineError("--frames: expected an integer, got '1.5'"));
  EXPECT_EXIT(parseOrDie({"--frames="}), ::testing::ExitedWithCode(2), oneLineError("--frames: expected an integer, got ''"));
  EXPECT_EXIT(parseOrDie({"--frames", " 3"}), ::testing::ExitedWithCode(2), oneLineError("--frames: expected an integer, got ' 3'"));
  EXPECT_EXIT(parseOrDie({"--frames", "2147483648"}), ::testing::ExitedWithCode(2),
              oneLineError("--frames: integer out of range [-2147483648, 2147483647], got '2147483648'"));
  EXPECT_EXIT(parseOrDie({"--frames", "99999999999999999999"}), ::testing::ExitedWithCode(2),
              oneLineError("--frames: integer out of range [-2147483648, 2147483647], got '99999999999999999999'"));
}

TEST(CliDeathTest, BadNumbers) {
  EXPECT_EXIT(parseOrDie({"--rate", "abc"}), ::testing::ExitedWithCode(2), oneLineError("--rate: expected a number, got 'abc'"));
  EXPECT_EXIT(parseOrDie({"--rate", "90hz"}), ::testing::ExitedWithCode(2), oneLineError("--rate: expected a number, got '90hz'"));
  EXPECT_EXIT(parseOrDie({"--rate="}), ::testing::ExitedWithCode(2), oneLineError("--rate: expected a number, got ''"));
  EXPECT_EXIT(parseOrDie({"--rate", "1e999"}), ::testing::ExitedWithCode(2), oneLineError("--rate: expected a finite number, got '1e999'"));
  EXPECT_EXIT(parseOrDie({"--rate", "-1e999"}), ::testing::ExitedWithCode(2),
              oneLineError("--rate: expected a finite number, got '-1e999'"));
  EXPECT_EXIT(parseOrDie({"--rate", "nan"}), ::testing::ExitedWithCode(2), oneLineError("--rate: expected a finite number, got 'nan'"));
  EXPECT_EXIT(parseOrDie({"--rate=NaN"}), ::testing::ExitedWithCode(2), oneLineError("--rate: expected a finite number, got 'NaN'"));
  EXPECT_EXIT(parseOrDie({"--rate", "inf"}), ::testing::ExitedWithCode(2), oneLineError("--rate: expected a finite number, got 'inf'"));
  EXPECT_EXIT(parseOrDie({"--rate", "-infinity"}), ::testing::ExitedWithCode(2),
              oneLineError("--rate: expected a finite number, got '-infinity'"));
}

TEST(CliDeathTest, FailFromMainIsOneLine) {
  Cli cli("prog", "");
  EXPECT_EXIT(cli.fail("--lab FILE is required"), ::testing::ExitedWithCode(2), oneLineError("--lab FILE is required"));
  EXPECT_EXIT(cli.fail("bad\nlab"), ::testing::ExitedWithCode(2), oneLineError("bad lab"));
}

TEST(CliDeathTest, HelpExitsZeroAndListsEveryOption) {
  const auto helpOnStderr = [](std::initializer_list<std::string> args) {
    ::dup2(STDERR_FILENO, STDOUT_FILENO);  // death tests see stderr only
    parseOrDie(args);
  };
  // Regex: the usage line, the synopsis, every option with its metavariable and default.
  const std::string re =
      "usage: prog \\[OPTIONS\\].*A test program\\..*"
      "--lab FILE +lab configuration \\(default: deploy/lab/local\\.pbtxt\\).*"
      "--out FILE +where to write\n.*"
      "--frames N +how many frames \\(default: 100\\).*"
      "--rate HZ +loop rate \\(default: 90\\).*"
      "--quiet +no progress lines\n.*"
      "--mesh FILE +a mesh \\(repeatable\\).*"
      "-h, --help +show this help and exit";
  EXPECT_EXIT(helpOnStderr({"--help"}), ::testing::ExitedWithCode(0), re);
  EXPECT_EXIT(helpOnStderr({"-h"}), ::testing::ExitedWithCode(0), re);
  // --help wins over earlier values and later errors.
  EXPECT_EXIT(helpOnStderr({"--frames", "5", "--help", "--bogus"}), ::testing::ExitedWithCode(0), "default: 100");
}

TEST(Cli, UsageShowsCurrentDefaultsAtDeclaration) {
  Cli cli("godhand-x", "Line one.\nLine two.");
  std::string s = "abc";
  int n = -3;
  double d = 0.25;
  bool on = true;
  std::vector<std::string> many{"a", "b"};
  cli.option("s", &s, "", "a string");
  cli.option("n", &n, "N", "an int\nsecond help line");
  cli.option("a-very-long-option-name-indeed", &d, "SECONDS", "a double");
  cli.flag("on", &on, "already on");
  cli.multi("m", &many, "X", "many");
  cli.epilog("Exit status: 0 ok, 2 bad arguments.");
  const std::string u = cli.usage();
  EXPECT_EQ(u.rfind("usage: godhand-x [OPTIONS]\n\nLine one.\nLine two.\n", 0), 0u) << u;
  EXPECT_NE(u.find("--s VALUE"), std::string::npos) << u;
  EXPECT_NE(u.find("a string (default: abc)"), std::string::npos) << u;
  EXPECT_NE(u.find("(default: -3)"), std::string::npos) << u;
  EXPECT_NE(u.find("an int\n"), std::string::npos) << u;
  EXPECT_NE(u.find("(default: 0.25)"), std::string::npos) << u;
  EXPECT_NE(u.find("--a-very-long-option-name-indeed SECONDS\n"), std::string::npos) << u;  // help on the next line
  EXPECT_NE(u.find("already on (default: on)"), std::string::npos) << u;
  EXPECT_NE(u.find("many (repeatable) (default: a b)"), std::string::npos) << u;
  EXPECT_NE(u.find("show this help and exit\n\nExit status: 0 ok, 2 bad arguments.\n"), std::string::npos) << u;
}

TEST(Cli, DeclarationMistakesThrow) {
  Cli cli("prog", "");
  bool b = false;
  int i = 0;
  cli.flag("x", &b, "");
  EXPECT_THROW(cli.flag("x", &b, ""), std::logic_error);
  EXPECT_THROW(cli.option("--x", &i, "N", ""), std::logic_error);
  EXPECT_THROW(cli.flag("help", &b, ""), std::logic_error);
  EXPECT_THROW(cli.flag("a=b", &b, ""), std::logic_error);
  EXPECT_THROW(cli.flag("", &b, ""), std::logic_error);
  EXPECT_THROW(cli.option("y", static_cast<int*>(nullptr), "N", ""), std::logic_error);
}

}  // namespace
}  // namespace godhand
