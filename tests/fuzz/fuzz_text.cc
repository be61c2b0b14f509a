// libFuzzer target: the protobuf text files a lab writes by hand (scene, lab configuration, hand
// model, sweep grid), through the parsers and validation the services use. The first input byte
// picks the file kind (0: scene, 1: lab, 2: hand model, 3: sweep grid). A bad file is one error
// line (SceneError, MeshError, SweepSpecError, LabError or ModelError), never a crash, a hang or
// a half-checked result: a parsed scene has finite placements, unit orientations and masses
// >= 0; a parsed model has finite rest poses. Mesh files a scene names are looked up (through
// the programs' loader, services/common/files.cc) in a directory that does not exist (a clear
// error).
#include <cmath>
#include <cstddef>
#include <cstdint>
#include <cstdlib>
#include <stdexcept>
#include <string>

#include "common/files.h"
#include "common/lab_config.h"
#include "common/sweep_spec.h"
#include "model/hand_model.h"
#include "scene/mesh_io.h"
#include "scene/scene_file.h"

namespace {
void oneLine(const std::exception& e) {
  const std::string what = e.what();
  if (what.empty() || what.find('\n') != std::string::npos) std::abort();
}

void checkScene(const godhand::Scene& s) {
  for (const godhand::SceneObject& o : s.objects) {
    if (!o.X_WO.p.allFinite() || !o.X_WO.q.coeffs().allFinite()) std::abort();
    if (!(std::fabs(o.X_WO.q.norm() - 1.0) < 1e-6)) std::abort();
    if (!std::isfinite(o.mass) || o.mass < 0.0) std::abort();
  }
}

void checkModel(const godhand::HandModel& m) {
  if (m.bodies.empty()) std::abort();
  for (const godhand::Pose& X : m.restPoses(godhand::Pose{}))
    if (!X.p.allFinite() || !X.q.coeffs().allFinite()) std::abort();
}
}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  if (size == 0) return 0;
  const std::string text(reinterpret_cast<const char*>(data + 1), size - 1);
  try {
    switch (data[0] % 4) {
      case 0: checkScene(godhand::parseScene(text, "fuzz.pbtxt", "/nonexistent-godhand-fuzz", godhand::meshFileLoader())); break;
      case 1: godhand::parseLab(text, "fuzz.pbtxt", "/nonexistent-godhand-fuzz"); break;
      case 2: checkModel(godhand::HandModel::fromText(text, "fuzz.pbtxt")); break;
      default: godhand::sweepSpecJson(godhand::parseSweepSpec(text, "fuzz.pbtxt")); break;
    }
  } catch (const godhand::SceneError& e) {
    oneLine(e);
  } catch (const godhand::MeshError& e) {
    oneLine(e);
  } catch (const godhand::LabError& e) {
    oneLine(e);
  } catch (const godhand::ModelError& e) {
    oneLine(e);
  } catch (const godhand::SweepSpecError& e) {
    oneLine(e);
  }  // anything else (std::out_of_range from a number conversion, bad_alloc) escapes: a finding
  return 0;
}
