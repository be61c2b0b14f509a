// The resolver's live merge rule (what it resolves, and when), apart from DDS and the solver:
// the newest proposal per cluster is kept (clusters may be at different frames: a lagging solver
// does not starve the others); a frame is resolved when every live cluster's proposal is in, or
// `merge_wait` frame periods after the first one came (a cluster silent for stale_after is not
// waited for and is held); with nothing new for stale_after, the held hands are re-published (as
// stale) so subscribers see that nothing moves them. A new ingest run (Stamp.run; frame numbers
// start again) replaces the old one; a straggler of an older run is late, and so is a new run
// whose source time is implausibly far ahead while the current run is live (anything accepted
// within stale_after). A cluster of which nothing was accepted for stale_after follows what comes
// again (its book restarts): no single sample, however far ahead its frame or time, stops the
// merge for longer. Injected clock.
#pragma once

#include <chrono>
#include <cstdint>
#include <vector>

namespace godhand::svc {

class LiveMerge {
 public:
  using Clock = std::chrono::steady_clock;
  enum class Offer { Accepted, NewRun, Superseded, Late };
  struct Decision {
    enum Kind { Wait, Resolve, Republish } kind = Wait;
    Clock::time_point until{};  ///< Wait: until when (or new data)
    std::uint64_t frame = 0;    ///< Resolve: the newest frame among the pending proposals; Republish: the last one
  };

  LiveMerge(size_t clusters, double period_s, double merge_wait, double stale_after_s, Clock::time_point now);

  /// A proposal of cluster h arrived. Accepted / NewRun (accepted; every cluster of the old run
  /// dropped) / Superseded (accepted, replacing an unresolved one: that one counts as late) /
  /// Late (dropped: not newer than what was resolved, or a straggler of an older run).
  Offer offer(size_t h, std::uint64_t run, std::uint64_t frame, std::int64_t source_ns, Clock::time_point now);
  Decision decide(bool have_scene, Clock::time_point now) const;
  /// The decision was carried out (resolved or re-published) at `now`.
  void published(const Decision& d, Clock::time_point now);

  bool pending(size_t h) const { return have_[h] != 0; }
  std::uint64_t frameOf(size_t h) const { return frame_[h]; }
  std::uint64_t run() const { return run_; }
  std::uint64_t done() const { return done_; }
  /// Times a cluster's book was restarted because everything that came was behind it.
  std::uint64_t recoveries() const { return recoveries_; }
  /// s: how far a new run's source time may lead the current run's beyond the time elapsed here.
  static constexpr double kRunSkew_s = 2.0;

 private:
  Clock::duration seconds(double s) const {
    return std::chrono::duration_cast<Clock::duration>(std::chrono::duration<double>(s));
  }
  size_t C_;
  double period_, merge_wait_, stale_after_;
  std::vector<unsigned char> have_;
  std::vector<std::uint64_t> frame_, done_h_;
  std::vector<Clock::time_point> last_in_;
  Clock::time_point first_pending_{}, last_publish_, last_accept_{};
  std::uint64_t run_ = 0, done_ = 0, recoveries_ = 0;
  std::int64_t run_source_ns_ = 0;
};

}  // namespace godhand::svc
