#include "source/live.h"

#include <cmath>

namespace godhand::bridges {

SourceOptions sourceOptions(const CalibrationText& t, std::int64_t frames) {
  SourceOptions o;
  o.frames = frames;
  if (!t.pose.empty()) o.X_WT = parsePose(t.pose);
  if (t.units == "mm" || t.units.empty()) o.units_to_m = 1e-3;
  else if (t.units == "cm") o.units_to_m = 1e-2;
  else if (t.units == "m") o.units_to_m = 1.0;
  else throw SourceError("tracker units '" + t.units + "': expected mm, cm or m");
  if (t.up == "y") o.y_up = true;
  else if (!t.up.empty() && t.up != "z") throw SourceError("tracker up axis '" + t.up + "': expected z or y");
  o.hand_sides = parseHandSides(t.hand_map);
  if (!t.palm_offset.empty()) {
    const Pose off = parsePose(t.palm_offset);
    if (t.palm_offset.find(',') == std::string::npos || off.p.norm() > 0.5)
      throw SourceError("palm offset '" + t.palm_offset + "': expected F,T,P metres, each within 0.5 m");
    if (!off.q.coeffs().isApprox(Quat::Identity().coeffs())) throw SourceError("palm offset '" + t.palm_offset + "': three values only");
    o.palm_offset_m = off.p;
  }
  if (t.max_datagram < 0 || t.max_datagram > 65507) throw SourceError("max datagram must be in 1..65507 bytes (0: 32768)");
  if (t.max_datagram > 0) o.max_datagram_bytes = static_cast<std::size_t>(t.max_datagram);
  // (Up to 1e9: a value that large switches the check off, as godhand-bench always allowed.)
  if (t.volume_m < 0.0 || t.volume_m > 1e9) throw SourceError("tracking volume must be in (0, 1e9] m (0: 50 m)");
  if (t.volume_m > 0.0) o.max_abs_position_m = t.volume_m;
  if (t.max_speed < 0.0 || t.max_speed > 1e9) throw SourceError("max speed must be in (0, 1e9] m/s (0: 30 m/s)");
  if (t.max_speed > 0.0) o.max_speed_mps = t.max_speed;
  return o;
}

bool SilenceMonitor::frame(double t) {
  last_ = t;
  if (silent_) {
    silent_ = false;
    return true;
  }
  return false;
}

bool SilenceMonitor::poll(double t) {
  if (last_ < 0.0) last_ = t;
  if (!silent_ && t - last_ >= silence_s_) {
    silent_ = true;
    ++silences_;
    return true;
  }
  return false;
}

}  // namespace godhand::bridges
