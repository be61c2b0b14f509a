// godhand-bench --compare mujoco: the same hands driven by MuJoCo (bridges/mujoco) on the same
// frames and targets, stepped right after godhand's pipeline in each frame (so both see the same
// machine load), and measured by the same figures (RunMetrics: penetration against the reference
// meshes, excess lag against the same free twin, frozen windows, free tracking error, joint gap).
#pragma once

#include <memory>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>

#include "mujoco/mujoco_hands.h"
#include "pipeline/run_metrics.h"

namespace godhand::bench {

class Comparison {
 public:
  /// Throws std::invalid_argument when the scene has dynamic objects and params.simulate (MuJoCo
  /// would have to simulate them too: not modelled here), or MuJoCo refuses the model.
  Comparison(const Scene& scene, std::vector<const HandModel*> models, std::vector<std::string> names,
             const PipelineParams& params, double frame_dt, const mujoco::Params& mj);

  /// One frame of MuJoCo (timed) on the inputs godhand got, then its figures; `world` is the
  /// scene the figures are measured against (static here: godhand's).
  void step(const std::vector<HandInput>& inputs, const CollisionWorld& world);

  RunSummary summary() const { return metrics_.summary(); }
  const std::vector<double>& stepUs() const { return step_us_; }
  std::string describeModel() const;

  /// The side-by-side lines (godhand's and MuJoCo's figures) and the JSON block "compare".
  std::string table(const RunSummary& godhand, const std::vector<double>& godhand_step_us) const;
  nlohmann::json json(const std::vector<double>& godhand_step_us) const;

 private:
  mujoco::Params params_;
  mujoco::Hands hands_;
  RunMetrics metrics_;
  std::vector<const HandModel*> models_;
  std::vector<double> step_us_;
};

}  // namespace godhand::bench
