// libFuzzer target: OpenXR / MediaPipe JSON Lines recordings (bridges/skeleton/jsonl.h). The
// first input byte picks the header (OpenXR or MediaPipe), the rest is the body: a bad header is
// a JsonlError (one line); every kept hand is finite with a unit palm quaternion.
#include <cmath>
#include <cstddef>
#include <cstdint>
#include <cstdlib>
#include <string>

#include "skeleton/jsonl.h"

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  if (size == 0) return 0;
  std::string text = (data[0] & 1) ? "{\"format\": \"godhand-openxr-hands\", \"version\": 1}\n"
                                    : "{\"format\": \"godhand-mediapipe-world\", \"version\": 1}\n";
  if (data[0] & 2) text.clear();  // also the header itself from the input
  text.append(reinterpret_cast<const char*>(data + 1), size - 1);
  try {
    const godhand::skeleton::JsonlRecording r = godhand::skeleton::readJsonl(text, "fuzz");
    for (const auto& f : r.frames)
      for (const auto& h : f.hands) {
        if (!h.X_W_palm.p.allFinite() || std::abs(h.X_W_palm.q.norm() - 1.0) > 1e-9) std::abort();
        for (const auto& fi : h.joints_W)
          for (const auto& j : fi)
            if (!j.allFinite()) std::abort();
      }
  } catch (const godhand::skeleton::JsonlError& e) {
    if (std::string(e.what()).find('\n') != std::string::npos) std::abort();
  }
  return 0;
}
