// The grid of a speed/accuracy sweep (idl/sweep.proto, protobuf text): parsed and validated for
// `godhand-bench --sweep SPEC.pbtxt`, which hands it to services/bench/sweep.py as JSON.
#pragma once

#include <stdexcept>
#include <string>
#include <utility>
#include <vector>

namespace godhand {

/// Bad sweep grid: one line "FILE:LINE: knobs[2].option: reason".
class SweepSpecError : public std::runtime_error {
 public:
  using std::runtime_error::runtime_error;
};

struct SweepSpec {
  bool product = false;  ///< every combination; else one knob at a time from the defaults
  std::vector<std::pair<std::string, std::vector<std::string>>> knobs;  ///< option -> values, in file order
};

/// Parses and validates a grid: every option starts with "--" and appears once, every knob has
/// at least one non-empty value. `source` names the file in errors.
SweepSpec parseSweepSpec(const std::string& text, const std::string& source);

/// Reads a grid file (throws SweepSpecError, also for a file that cannot be read).
SweepSpec loadSweepSpec(const std::string& path);

/// The grid in sweep.py's JSON form: {"mode": "each"|"product", "knobs": {OPTION: [VALUES]}}.
std::string sweepSpecJson(const SweepSpec& spec);

/// `godhand-bench --sweep GRID ...` as the sweep.py command it stands for: `python3 SCRIPT --bench
/// BENCH --grid GRID` and the run's options (--recording, --mesh (repeatable), --scene, --frames,
/// --json, --plot, --target); any other option is an error (it belongs in the grid as a knob).
/// `args` are the command-line arguments after the program name.
std::vector<std::string> sweepCommand(const std::vector<std::string>& args, const std::string& script,
                                      const std::string& bench);

}  // namespace godhand
