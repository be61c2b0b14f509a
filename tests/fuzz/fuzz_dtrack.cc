// libFuzzer target: one DTrack datagram through the stream decoder (parser, completeness,
// frame counter, hand mapping). The input is split at 0xff bytes into several datagrams so that
// the decoder's state (lines seen, last frame) is fuzzed too. Properties checked beyond "no
// crash": every accepted frame's hands are finite, and counts add up.
#include <cmath>
#include <cstddef>
#include <cstdint>
#include <cstdlib>
#include <string_view>

#include "dtrack/dtrack.h"

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  godhand::dtrack::Decoder dec;
  godhand::leap::TrackerFrame f;
  const std::string_view all(reinterpret_cast<const char*>(data), size);
  std::size_t pos = 0, n = 0;
  while (pos <= all.size()) {
    std::size_t e = all.find('\xff', pos);
    if (e == std::string_view::npos) e = all.size();
    ++n;
    if (dec.feed(all.substr(pos, e - pos), 0, &f))
      for (const auto& h : f.hands) {
        if (!h.X_W_palm.p.allFinite() || !h.X_W_palm.q.coeffs().allFinite()) std::abort();
        for (const auto& fi : h.joints_W)
          for (const auto& j : fi)
            if (!j.allFinite()) std::abort();
      }
    pos = e + 1;
  }
  if (dec.accepted() + dec.rejectedTotal() != dec.received() || dec.received() != n) std::abort();
  return 0;
}
