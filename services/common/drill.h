// Fault drills of godhand-launch: `--kill SERVICE@WHEN`, timed from the first frame of the replay
// (the first HandTarget the launcher sees), never from the launcher's own start (start-up takes
// 1-4 s, so a time from the start lands before, during or after the replay).
//
//   SERVICE@S, SERVICE@Ss   S seconds after the replay starts (scene@2, scene@2.5s)
//   SERVICE@fN              when the replay reaches tracker frame N (scene@f120), N >= 1
//
// SERVICE and WHEN must both be given; the launcher checks SERVICE against the lab.
#pragma once

#include <cstdint>
#include <stdexcept>
#include <string>

namespace godhand {

struct Drill {
  std::string spec;          ///< as given
  std::string service;       ///< "scene", "solver/right", "ingest", ...
  bool by_frame = false;     ///< true: at `frame`, false: at `seconds` after the replay starts
  double seconds = 0.0;
  std::uint64_t frame = 0;

  /// Due now? replay_s: seconds since the replay's first frame (< 0: not started);
  /// replay_frame: newest tracker frame of the replay seen.
  bool due(double replay_s, std::uint64_t replay_frame) const {
    if (replay_s < 0.0) return false;
    return by_frame ? replay_frame >= frame : replay_s >= seconds;
  }
};

/// Parses one --kill value; std::invalid_argument with one line naming the value otherwise.
Drill parseDrill(const std::string& spec);

}  // namespace godhand
