#include "common/output_rate.h"

namespace godhand {

void OutputRate::beat(const std::string& service, std::int64_t pid, std::int64_t time_ns, std::uint64_t samples_out) {
  auto it = beats_.find(service);
  if (it == beats_.end() || it->second.pid != pid || time_ns < it->second.t1 || samples_out < it->second.n1) {
    // The first heartbeat of this process (or a counter or clock that went back): start again.
    Beats& b = beats_[service];
    b = Beats{};
    b.pid = pid;
    b.t1 = time_ns;
    b.n1 = samples_out;
    return;
  }
  Beats& b = it->second;
  if (time_ns == b.t1) {  // the same heartbeat again (or none between): nothing to measure
    b.n1 = samples_out;
    return;
  }
  b.t0 = b.t1;
  b.n0 = b.n1;
  b.t1 = time_ns;
  b.n1 = samples_out;
  b.two = true;
}

double OutputRate::perSecond(const std::string& service) const {
  const auto it = beats_.find(service);
  if (it == beats_.end() || !it->second.two || it->second.t1 <= it->second.t0) return -1.0;
  const Beats& b = it->second;
  return static_cast<double>(b.n1 - b.n0) / (static_cast<double>(b.t1 - b.t0) * 1e-9);
}

}  // namespace godhand
