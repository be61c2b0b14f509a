// A tracker source's counts as the launch report gives them (issue 11): records / datagrams
// received, frames accepted, rejections by reason. The ingest puts them in every heartbeat
// (ServiceStatus.source, bounded: boundReasons), so a launcher gets them from an ingest on any
// host; the launcher sums them over ingest runs (SourceTally).
//
// Honesty rules kept here: these are counts, never maxima or frame numbers; a run's figures are
// the newest heartbeat of that run (counters only grow within a run); a restarted ingest is a new
// run (its source counts from 0 again) and runs are summed, so a record counted by a killed run
// stays counted. What a killed run counted after its last heartbeat (period 0.5 s) is not known
// and not invented. No reason is ever dropped to fit the wire bound: the remainder is summed
// under kOtherReasons, so the total of the rejections is always exact.
//
// A recording's frames that a run never played are not received (neither accepted nor
// rejected): they are counted as not played, by reason (bridges' SourceStats::not_played). While a
// run plays, its heartbeats count the rest of the recording as kNotPlayedYet; a run that ended
// without a final count (killed) keeps that figure of its last heartbeat, and the report says so
// (kNotPlayedNoFinalCount). So received = accepted + rejected holds for what was received (for a
// source of one frame per record whose rejections are of whole records, e.g. DTrack datagrams).
#pragma once

#include <cstddef>
#include <cstdint>
#include <map>
#include <string>
#include <utility>
#include <vector>

namespace godhand {

struct SourceCounts {
  std::uint64_t received = 0;  ///< records / datagrams that came in (of a recording: of the frames played, and the rejected ones)
  std::uint64_t accepted = 0;  ///< frames delivered
  std::map<std::string, std::uint64_t> rejected;  ///< by reason (only nonzero counts)
  std::map<std::string, std::uint64_t> not_played;  ///< a recording's records never played, by reason (only nonzero counts)
  std::uint64_t rejectedTotal() const;
  std::uint64_t notPlayedTotal() const;
  bool operator==(const SourceCounts& o) const {
    return received == o.received && accepted == o.accepted && rejected == o.rejected && not_played == o.not_played;
  }
};

/// The wire's bounds (idl/godhand.idl ServiceStatus.source: sequence<ReasonCount, 16>, string<64>).
constexpr std::size_t kWireReasons = 16;
constexpr std::size_t kWireReasonChars = 64;
/// Where the reasons beyond the wire's bound go (summed).
constexpr const char* kOtherReasons = "other reasons";
/// The wire's bound of not-played reasons (ServiceStatus.source.not_played: sequence<ReasonCount, 4>).
constexpr std::size_t kWireNotPlayedReasons = 4;
/// A playing run's rest of the recording (the ingest's heartbeats while it plays).
constexpr const char* kNotPlayedYet = "not played yet";
/// The not-played reason of a run that its --duration stopped (durationReachedReason): the one
/// reason a launcher reads, to expect only what that run published (Delivery::expected).
std::string durationReachedReason(double duration_s);
bool isDurationReached(const std::string& reason);
/// What the report calls kNotPlayedYet of a run whose last count is all there is.
constexpr const char* kNotPlayedNoFinalCount = "by the run's last heartbeat, no final count (killed, or still running)";

/// The reasons as they fit the wire: each name cut to at most max_chars bytes (a bounded IDL
/// string; names that become equal when cut are summed), zero counts left out, and when more than
/// max_reasons remain, the max_reasons - 1 largest kept (ties: by name) and the rest summed under
/// kOtherReasons. In name order. The total is always preserved.
std::vector<std::pair<std::string, std::uint64_t>> boundReasons(const std::map<std::string, std::uint64_t>& reasons,
                                                                std::size_t max_reasons = kWireReasons,
                                                                std::size_t max_chars = kWireReasonChars);

/// A source's counts from a reason list (as bridges::SourceStats::by_reason gives it; repeated
/// reasons are summed, zero counts left out).
std::map<std::string, std::uint64_t> reasonMap(const std::vector<std::pair<std::string, std::uint64_t>>& by_reason);

/// The launcher's sum over ingest runs: update() with every heartbeat's counts and its run.
class SourceTally {
 public:
  /// run 0: the sample carries no source (another service, or an ingest before its source opened).
  void update(std::uint64_t run, const SourceCounts& counts);
  std::size_t runs() const { return runs_.size(); }
  bool any() const { return !runs_.empty(); }
  /// Summed over the runs (each run: its newest counts), for the report made once the runs are
  /// over: a run's kNotPlayedYet is kNotPlayedNoFinalCount (its final heartbeat would have said
  /// why the rest was not played, or had nothing left).
  SourceCounts total() const;
  /// Run `run`'s newest counts say that its --duration stopped it before the end of its recording
  /// (a not-played reason durationReachedReason): false while it plays, when killed, stopped by a
  /// signal, or when its final heartbeat never came.
  bool stoppedByDuration(std::uint64_t run) const;
  /// The same of the newest run (run ids grow with the ingest's start time); false when none.
  bool lastRunStoppedByDuration() const { return !runs_.empty() && stoppedByDuration(runs_.rbegin()->first); }

 private:
  std::map<std::uint64_t, SourceCounts> runs_;
};

/// "source: received N, accepted M, rejected K (reason a, reason b ...)": the report's line.
/// "(none)" when nothing was rejected; "; not played P (reason p, ...)" when frames of a recording
/// were not played; ", over R ingest runs (summed)" when runs > 1.
std::string describeSource(const SourceCounts& c, std::size_t runs = 1);

}  // namespace godhand
