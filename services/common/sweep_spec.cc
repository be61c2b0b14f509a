#include "common/sweep_spec.h"

#include <google/protobuf/text_format.h>
#include <unistd.h>

#include <cstdio>
#include <fstream>
#include <set>
#include <sstream>

#include "model/text_proto.h"
#include "sweep.pb.h"

namespace godhand {

namespace {
using google::protobuf::TextFormat;

std::string jsonString(const std::string& s) {
  std::string out = "\"";
  for (const char ch : s) {
    const unsigned char c = static_cast<unsigned char>(ch);
    if (c == '"' || c == '\\') {
      out += '\\';
      out += ch;
    } else if (c < 0x20) {
      char buf[8];
      std::snprintf(buf, sizeof buf, "\\u%04x", c);
      out += buf;
    } else {
      out += ch;
    }
  }
  return out + "\"";
}
}  // namespace

SweepSpec parseSweepSpec(const std::string& text, const std::string& source) {
  pb::SweepGrid msg;
  TextFormat::ParseInfoTree tree;
  std::string syntax;
  if (!parseTextProto(text, &msg, &tree, &syntax, "unparsable sweep grid")) throw SweepSpecError(source + ":" + syntax);
  const auto* f_knobs = msg.GetDescriptor()->FindFieldByName("knobs");
  auto lineOf = [&](int i) {
    const auto loc = tree.GetLocation(f_knobs, i);
    return loc.line >= 0 ? loc.line + 1 : 1;
  };
  // An option as a message shows it: one line, control bytes escaped (\n, \xNN).
  auto shown = [](const std::string& o) {
    std::string out;
    for (const unsigned char c : o) {
      if (c == '\n') out += "\\n";
      else if (c < 0x20 || c == 0x7f) {
        char b[8];
        std::snprintf(b, sizeof b, "\\x%02x", c);
        out += b;
      } else out += static_cast<char>(c);
    }
    return out;
  };
  auto printable = [](const std::string& o) {
    for (const unsigned char c : o)
      if (c <= 0x20 || c == 0x7f) return false;
    return true;
  };
  SweepSpec spec;
  spec.product = msg.mode() == pb::SweepGrid::PRODUCT;
  if (msg.knobs_size() == 0) throw SweepSpecError(source + ":1: knobs: a sweep grid needs at least one knob");
  std::set<std::string> seen;
  for (int i = 0; i < msg.knobs_size(); ++i) {
    const pb::SweepKnob& k = msg.knobs(i);
    const std::string at = source + ":" + std::to_string(lineOf(i)) + ": knobs[" + std::to_string(i) + "]";
    if (k.option().size() < 3 || k.option().compare(0, 2, "--") != 0 || !printable(k.option()))
      throw SweepSpecError(at + ".option: '" + shown(k.option()) + "' is not a godhand-bench option (--NAME)");
    if (!seen.insert(k.option()).second) throw SweepSpecError(at + ".option: " + k.option() + " appears twice");
    if (k.values_size() == 0) throw SweepSpecError(at + ".values: " + k.option() + " has no values");
    std::vector<std::string> values;
    for (const std::string& v : k.values()) {
      if (v.find_first_not_of(" \t") == std::string::npos)
        throw SweepSpecError(at + ".values: " + k.option() + " has an empty value");
      values.push_back(v);
    }
    spec.knobs.emplace_back(k.option(), std::move(values));
  }
  return spec;
}

SweepSpec loadSweepSpec(const std::string& path) {
  std::ifstream in(path, std::ios::binary);
  if (!in) throw SweepSpecError(path + ": cannot open sweep grid");
  std::ostringstream ss;
  ss << in.rdbuf();
  return parseSweepSpec(ss.str(), path);
}

std::string sweepSpecJson(const SweepSpec& spec) {
  std::string out = std::string("{\"mode\": \"") + (spec.product ? "product" : "each") + "\", \"knobs\": {";
  for (size_t i = 0; i < spec.knobs.size(); ++i) {
    if (i) out += ", ";
    out += jsonString(spec.knobs[i].first) + ": [";
    for (size_t j = 0; j < spec.knobs[i].second.size(); ++j) out += (j ? ", " : "") + jsonString(spec.knobs[i].second[j]);
    out += "]";
  }
  return out + "}}";
}

std::vector<std::string> sweepCommand(const std::vector<std::string>& args, const std::string& script,
                                      const std::string& bench) {
  static const std::set<std::string> kPassed = {"--recording", "--mesh", "--scene", "--frames", "--repeat", "--json", "--plot", "--target"};
  // Debian's python3 (where apt installs python3-matplotlib, for --plot) when it is there.
  std::vector<std::string> cmd = {::access("/usr/bin/python3", X_OK) == 0 ? "/usr/bin/python3" : "python3", script, "--bench", bench};
  std::string grid;
  for (size_t i = 0; i < args.size(); ++i) {
    const std::string& f = args[i];
    if (i + 1 >= args.size()) throw SweepSpecError(f + ": missing value (or not an option of --sweep)");
    if (f == "--sweep") {
      if (!grid.empty()) throw SweepSpecError("--sweep given twice");
      grid = args[++i];
    } else if (kPassed.count(f)) {
      cmd.push_back(f);
      cmd.push_back(args[++i]);
    } else {
      throw SweepSpecError("with --sweep, " + f +
                           " belongs in the grid (a knob), not on the command line; a sweep takes --recording, --mesh, "
                           "--scene, --frames, --repeat, --json, --plot and --target");
    }
  }
  if (grid.empty()) throw SweepSpecError("--sweep GRID.pbtxt is required");
  cmd.push_back("--grid");
  cmd.push_back(grid);
  return cmd;
}

}  // namespace godhand
