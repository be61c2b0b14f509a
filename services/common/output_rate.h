// What a service output per second, from its heartbeats (ServiceStatus: pid, time_ns,
// samples_out): the samples it wrote between its two newest heartbeats of one process, over the
// time between them (its own clock).
//
// Why: a heartbeat's rate_hz counts the frames the service processed. For the scene those are
// the steps that applied new ContactForces (its inputs), while it publishes a SceneState at every
// step of its own clock, forces or not: with the resolver stopped, the live line read "scene 0 Hz"
// while the scene published 24 states a second. The launcher's line shows the scene's states per
// second from this instead. Rules: only two heartbeats of the same process count (a restarted
// process starts again: its former process's counters are not its output); a counter that went
// down, or a heartbeat time that did not advance, starts again too (nothing is made up).
#pragma once

#include <cstdint>
#include <map>
#include <string>

namespace godhand {

class OutputRate {
 public:
  /// A heartbeat of `service` from process `pid`, sent at time_ns (the sender's clock), with its
  /// samples_out counter.
  void beat(const std::string& service, std::int64_t pid, std::int64_t time_ns, std::uint64_t samples_out);
  /// Samples written per second between the service's two newest heartbeats of its current
  /// process; < 0 when not known (fewer than two of them).
  double perSecond(const std::string& service) const;

 private:
  struct Beats {
    std::int64_t pid = 0, t0 = 0, t1 = 0;
    std::uint64_t n0 = 0, n1 = 0;
    bool two = false;  // t0/n0 hold an earlier heartbeat of the same process
  };
  std::map<std::string, Beats> beats_;
};

}  // namespace godhand
