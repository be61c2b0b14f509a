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
#pragma once

#include <cstddef>
#include <cstdint>
#include <map>
#include <string>
#include <utility>
#include <vector>

namespace godhand {

struct SourceCounts {
  std::uint64_t received = 0;  ///< records / datagrams that came in
  std::uint64_t accepted = 0;  ///< frames delivered
  std::map<std::string, std::uint64_t> rejected;  ///< by reason (only nonzero counts)
  std::uint64_t rejectedTotal() const;
  bool operator==(const SourceCounts& o) const { return received == o.received && accepted == o.accepted && rejected == o.rejected; }
};

/// The wire's bounds (idl/godhand.idl ServiceStatus.source: sequence<ReasonCount, 16>, string<64>).
constexpr std::size_t kWireReasons = 16;
constexpr std::size_t kWireReasonChars = 64;
/// Where the reasons beyond the wire's bound go (summed).
constexpr const char* kOtherReasons = "other reasons";

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
  /// Summed over the runs (each run: its newest counts).
  SourceCounts total() const;

 private:
  std::map<std::uint64_t, SourceCounts> runs_;
};

/// "source: received N, accepted M, rejected K (reason a, reason b ...)": the report's line.
/// "(none)" when nothing was rejected; ", over R ingest runs (summed)" when runs > 1.
std::string describeSource(const SourceCounts& c, std::size_t runs = 1);

}  // namespace godhand
