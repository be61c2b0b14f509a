// The launcher's watchdog: ages every service's heartbeats (ServiceStatus, period 0.5 s) on the
// launcher's clock, injected by the caller (every call takes `now`), so that a silent or frozen
// service (killed, SIGSTOPped, hung, partitioned) is noticed within `silent_after` seconds and
// never shown as "running" from its last heartbeat.
//
// A service is Unknown until its first heartbeat, then Alive while its newest heartbeat is at
// most silent_after old, Silent afterwards (until a heartbeat comes again). Each Silent spell is
// an episode (start, end; end < 0 while it lasts). reset() forgets a service (it is being
// restarted: Unknown until its new process beats).
//
// The watchdog's own pauses: a gap between two update() calls of more than half of silent_after
// (the launcher's loop calls it every ~20 ms) is time nobody was looking (the launcher stopped
// or starved, the machine stalled), and the heartbeats of that time may still be in the
// launcher's sockets. It is not counted against any service: every newest heartbeat is moved on
// by the gap less a quarter of silent_after (a 2.5 s stall of the launcher had it kill and
// restart all five healthy services; the quarter keeps a launcher whose every loop is slow
// finding a dead service, later). Each such pause is recorded (pauses()). The credit only delays
// the verdict: silentFor() and an episode's start are the service's own silence, from its newest
// heartbeat (they under-reported it by the credit before).
#pragma once

#include <chrono>
#include <cstdint>
#include <map>
#include <string>
#include <vector>

namespace godhand {

class Watchdog {
 public:
  using Clock = std::chrono::steady_clock;
  enum class Health { Unknown, Alive, Silent };
  struct Episode {
    std::string service;
    double start_s = 0.0;  ///< seconds since the watchdog's origin when it went silent
    double end_s = -1.0;   ///< when it beat again, was reset, or < 0: still silent
    bool reset = false;    ///< ended by reset() (killed, restarted, ended), not by a heartbeat
  };

  struct Pause {
    double start_s = 0.0;     ///< seconds since the origin: the last update() before the gap
    double duration_s = 0.0;  ///< the gap
  };

  Watchdog(double silent_after_s, Clock::time_point origin) : silent_after_(silent_after_s), origin_(origin) {}

  /// A heartbeat of `service` arrived at `now`.
  void beat(const std::string& service, Clock::time_point now);
  /// Re-evaluates every service at `now`; returns the services that became Silent in this call.
  std::vector<std::string> update(Clock::time_point now);
  Health health(const std::string& service) const;
  /// Seconds since the newest heartbeat (< 0: none yet), the watchdog's own pauses included (they
  /// only delay its verdict).
  double silentFor(const std::string& service, Clock::time_point now) const;
  void reset(const std::string& service, Clock::time_point now);
  const std::vector<Episode>& episodes() const { return episodes_; }
  /// The caller did not watch from its last update() until `now` on purpose (its own work at the
  /// end of a run): not counted against any service, and not recorded as a pause.
  void resumeAfterOwnWork(Clock::time_point now) { shiftOver(now, false); }
  /// The watchdog's own pauses longer than silent_after (see above), the first kMaxPauses of them;
  /// pauseCount() counts them all.
  const std::vector<Pause>& pauses() const { return pauses_; }
  std::uint64_t pauseCount() const { return pause_count_; }
  static constexpr std::size_t kMaxPauses = 32;
  double silentAfter() const { return silent_after_; }

 private:
  struct Entry {
    Clock::time_point last{};  ///< the newest heartbeat, as it came (silentFor, an episode's start)
    Clock::time_point aged{};  ///< the same, moved on by this watchdog's own pauses: what is aged
    bool silent = false;
    int episode = -1;
  };
  double seconds(Clock::time_point t) const { return std::chrono::duration<double>(t - origin_).count(); }
  void endEpisode(Entry& e, Clock::time_point now, bool by_reset);
  /// A gap since the last update longer than half of silent_after moves every newest heartbeat on
  /// by it (recorded as a pause when `record`); then now is the last update.
  void shiftOver(Clock::time_point now, bool record);

  double silent_after_;
  Clock::time_point origin_;
  std::map<std::string, Entry> entries_;
  std::vector<Episode> episodes_;
  Clock::time_point last_update_{};
  std::vector<Pause> pauses_;
  std::uint64_t pause_count_ = 0;
};

}  // namespace godhand
