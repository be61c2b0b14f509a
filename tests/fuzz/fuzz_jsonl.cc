// libFuzzer target: the text recording formats of bridges/skeleton and bridges/synthetic. The
// first input byte picks the reader: bit 2 set -> Aria MPS CSV (bit 3: with the real header
// prepended), bit 4 set -> a synthetic script, else OpenXR / MediaPipe JSON Lines (bit 0 picks
// the header, bit 1: none). A bad file is one error line; every kept hand is finite with a unit
// palm quaternion.
#include <cmath>
#include <cstddef>
#include <cstdint>
#include <cstdlib>
#include <string>

#include "skeleton/aria.h"
#include "skeleton/jsonl.h"
#include "synthetic/synthetic.h"

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  if (size == 0) return 0;
  auto checkHands = [](const std::vector<godhand::leap::TrackerFrame>& frames) {
    for (const auto& f : frames)
      for (const auto& h : f.hands) {
        if (!h.X_W_palm.p.allFinite() || std::abs(h.X_W_palm.q.norm() - 1.0) > 1e-9) std::abort();
        for (const auto& fi : h.joints_W)
          for (const auto& j : fi)
            if (!j.allFinite()) std::abort();
      }
  };
  const std::string body(reinterpret_cast<const char*>(data + 1), size - 1);
  if (data[0] & 16) {
    if (size > 4096) return 0;  // a script may ask for long motions; keep runs short
    try {
      const auto sc = godhand::synthetic::parseScript(body, "fuzz");
      double total = 0;
      for (const auto& c : sc.commands) total += c.seconds;
      if (total * sc.rate_hz > 2e5) return 0;  // valid but too long to generate in a fuzz run
      checkHands(godhand::synthetic::generate(sc).frames);
    } catch (const godhand::synthetic::ScriptError& e) {
      if (std::string(e.what()).find('\n') != std::string::npos) std::abort();
    }
    return 0;
  }
  if (data[0] & 4) {
    std::string csv;
    if (data[0] & 8) {
      csv = "tracking_timestamp_us";
      for (const char* side : {"left", "right"}) {
        csv += std::string(",") + side + "_tracking_confidence";
        for (int i = 0; i < 21; ++i)
          for (const char* a : {"x", "y", "z"}) csv += std::string(",t") + a + "_" + side + "_landmark_" + std::to_string(i) + "_device";
      }
      csv += "\n";
    }
    csv += body;
    try {
      checkHands(godhand::skeleton::readAriaCsv(csv, "fuzz").frames);
    } catch (const godhand::skeleton::JsonlError& e) {
      if (std::string(e.what()).find('\n') != std::string::npos) std::abort();
    }
    return 0;
  }
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
