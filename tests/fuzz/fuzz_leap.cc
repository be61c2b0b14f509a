// libFuzzer target: a Leap Motion JSON recording (bridges/leap) from bytes. Bad input must end
// in a RecordingError (one line) or a recording whose every hand is finite.
#include <cstddef>
#include <cstdint>
#include <cstdlib>
#include <string>

#include "leap/leap_recording.h"

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  const std::string text(reinterpret_cast<const char*>(data), size);
  try {
    const godhand::leap::Recording r = godhand::leap::Recording::fromText(text, "fuzz");
    for (const auto& f : r.frames())
      for (const auto& h : f.hands) {
        if (!h.X_W_palm.p.allFinite() || !(h.confidence >= 0.0 && h.confidence <= 1.0)) std::abort();
        for (const auto& fi : h.joints_W)
          for (const auto& j : fi)
            if (!j.allFinite()) std::abort();
      }
  } catch (const godhand::leap::RecordingError& e) {
    if (std::string(e.what()).find('\n') != std::string::npos) std::abort();
  }
  return 0;
}
