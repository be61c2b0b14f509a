// The sweep grid (idl/sweep.proto) and `godhand-bench --sweep` as the sweep.py command.
#include <gtest/gtest.h>

#include <string>
#include <vector>

#include <unistd.h>

#include "common/sweep_spec.h"

namespace godhand {
namespace {

std::string errorOf(const std::string& text) {
  try {
    parseSweepSpec(text, "g.pbtxt");
  } catch (const SweepSpecError& e) {
    return e.what();
  }
  return "";
}

TEST(SweepSpec, ParsesKnobsInOrderAndWritesSweepPyJson) {
  const SweepSpec s = parseSweepSpec(
      "mode: PRODUCT\nknobs { option: \"--substeps\" values: \"1\" values: \"3\" }\n"
      "knobs { option: \"--solver\" values: \"pgs --pgs-iterations 30\" }\n",
      "g.pbtxt");
  EXPECT_TRUE(s.product);
  ASSERT_EQ(s.knobs.size(), 2u);
  EXPECT_EQ(s.knobs[0].first, "--substeps");
  EXPECT_EQ(s.knobs[0].second, (std::vector<std::string>{"1", "3"}));
  EXPECT_EQ(s.knobs[1].second, (std::vector<std::string>{"pgs --pgs-iterations 30"}));
  EXPECT_EQ(sweepSpecJson(s),
            "{\"mode\": \"product\", \"knobs\": {\"--substeps\": [\"1\", \"3\"], \"--solver\": [\"pgs --pgs-iterations 30\"]}}");
  EXPECT_FALSE(parseSweepSpec("knobs { option: \"--a\" values: \"x\\\"y\" }", "g").product);  // EACH is the default
  EXPECT_EQ(sweepSpecJson(parseSweepSpec("knobs { option: \"--a\" values: \"x\\\"y\" }", "g")),
            "{\"mode\": \"each\", \"knobs\": {\"--a\": [\"x\\\"y\"]}}");
}

TEST(SweepSpec, BadGridsAreOneLineWithTheirLine) {
  EXPECT_EQ(errorOf(""), "g.pbtxt:1: knobs: a sweep grid needs at least one knob");
  EXPECT_EQ(errorOf("\nknobs { option: \"substeps\" values: \"1\" }"),
            "g.pbtxt:2: knobs[0].option: 'substeps' is not a godhand-bench option (--NAME)");
  EXPECT_EQ(errorOf("knobs { option: \"--a\" values: \"1\" }\nknobs { option: \"--a\" values: \"2\" }"),
            "g.pbtxt:2: knobs[1].option: --a appears twice");
  EXPECT_EQ(errorOf("knobs { option: \"--a\" }"), "g.pbtxt:1: knobs[0].values: --a has no values");
  // An option with a line break or a control byte: refused, shown escaped on one line (a fuzz
  // finding: the message carried the raw newline).
  EXPECT_EQ(errorOf("knobs { option: \"-nd-model a\\nb\" values: \"4\" }"),
            "g.pbtxt:1: knobs[0].option: '-nd-model a\\nb' is not a godhand-bench option (--NAME)");
  EXPECT_EQ(errorOf("knobs { option: \"--a\\tb\" values: \"4\" }"),
            "g.pbtxt:1: knobs[0].option: '--a\\x09b' is not a godhand-bench option (--NAME)");
  EXPECT_EQ(errorOf("knobs { option: \"--a\" values: \" \" }"), "g.pbtxt:1: knobs[0].values: --a has an empty value");
  const std::string syntax = errorOf("knobs { option: --a }");
  EXPECT_EQ(syntax.rfind("g.pbtxt:1:", 0), 0u) << syntax;
  EXPECT_NE(errorOf("mode: SOMETIMES").find("g.pbtxt:1:"), std::string::npos);
  for (const std::string& e : {errorOf(""), syntax, errorOf("mode: SOMETIMES")}) EXPECT_EQ(e.find('\n'), std::string::npos);
  try {
    loadSweepSpec("/nonexistent/grid.pbtxt");
    ADD_FAILURE() << "no error";
  } catch (const SweepSpecError& e) {
    EXPECT_STREQ(e.what(), "/nonexistent/grid.pbtxt: cannot open sweep grid");
  }
}

TEST(SweepSpec, BenchSweepIsTheSweepPyCommand) {
  EXPECT_EQ(sweepCommand({"--recording", "r.json", "--sweep", "g.pbtxt", "--mesh", "a.obj", "--mesh", "b.obj:0.2", "--json",
                          "o.json", "--target", "penetration_max_m<=1e-4"},
                         "/src/sweep.py", "/bin/godhand-bench"),
            (std::vector<std::string>{::access("/usr/bin/python3", X_OK) == 0 ? "/usr/bin/python3" : "python3", "/src/sweep.py", "--bench", "/bin/godhand-bench", "--recording", "r.json",
                                      "--mesh", "a.obj", "--mesh", "b.obj:0.2", "--json", "o.json", "--target",
                                      "penetration_max_m<=1e-4", "--grid", "g.pbtxt"}));
  auto errorFor = [](const std::vector<std::string>& args) {
    try {
      sweepCommand(args, "s.py", "b");
    } catch (const SweepSpecError& e) {
      return std::string(e.what());
    }
    return std::string();
  };
  EXPECT_NE(errorFor({"--sweep", "g", "--substeps", "1"}).find("--substeps belongs in the grid"), std::string::npos);
  EXPECT_NE(errorFor({"--sweep", "g", "--recording"}).find("--recording: missing value"), std::string::npos);
  EXPECT_EQ(errorFor({"--recording", "r"}), "--sweep GRID.pbtxt is required");
  EXPECT_EQ(errorFor({"--sweep", "a", "--sweep", "b"}), "--sweep given twice");
}

}  // namespace
}  // namespace godhand
