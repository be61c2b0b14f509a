// A one-body "hand" (a single God object driven by the tracker segment "probe") for the
// pipeline tests: `shape_text` is the body's shape in hand-model text, e.g. "sphere { radius: 0.01 }".
#pragma once

#include <fstream>
#include <sstream>
#include <stdexcept>
#include <string>

#include "model/hand_model.h"

namespace godhand::testing {

inline HandModel probeModel(const std::string& shape_text, double mass) {
  const std::string text = "name: \"probe\"\nbodies {\n  name: \"probe\"\n  " + shape_text +
                           "\n  mass: " + std::to_string(mass) +
                           "\n  rest_position { x: 0 y: 0 z: 0 }\n  rest_orientation { w: 1 x: 0 y: 0 z: 0 }\n"
                           "  tracker_segment: \"probe\"\n}\n";
  return HandModel::fromText(text, "probe");
}

/// The model file at `path` with `rotation_weight: WEIGHT` (idl/hand_model.proto), e.g. the paper's
/// SOLID beside the shipped default.
inline HandModel withRotationWeight(const std::string& path, const std::string& weight) {
  std::ifstream in(path);
  if (!in) throw std::runtime_error(path + ": cannot open model file");
  std::ostringstream text;
  text << in.rdbuf();
  return HandModel::fromText("rotation_weight: " + weight + "\n" + text.str(), path);
}

}  // namespace godhand::testing
