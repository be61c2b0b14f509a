#include "common/latency_figures.h"

namespace godhand {

void LatencyFigures::add(double age_us, bool stale) {
  if (!(age_us > 0)) return;  // not measured (also NaN)
  if (stale) {
    stale_.add(age_us);
    return;
  }
  fresh_.add(age_us);
  window_.push_back(age_us);
}

}  // namespace godhand
