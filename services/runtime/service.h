// What every godhand service process shares: the common command-line options, the lab
// configuration, the Fast DDS participant (through services/dds only), the ServiceStatus
// heartbeat, counters printed on SIGINT/SIGTERM, latency statistics, and the wait that keeps
// heartbeats going and returns on a stop request.
#pragma once

#include <chrono>
#include <cstdint>
#include <functional>
#include <map>
#include <memory>
#include <string>
#include <vector>

#include "common/cli.h"
#include "common/lab_config.h"
#include "common/source_counts.h"
#include "dds/dds.h"
#include "dds/topics.h"
#include "godhand.h"

namespace godhand::svc {

using SteadyClock = std::chrono::steady_clock;

struct CommonOptions {
  std::string lab;               ///< lab configuration (default: the shipped deploy/lab/local.pbtxt)
  int domain = -1;               ///< -1: the lab's
  std::string profiles;          ///< "": the lab's, else the DDS layer's default
  bool lockstep = false;
  std::string scene;             ///< "": the lab's
  double frame_rate = 0.0;       ///< Hz; 0: the rate of the lab's recording
  double deadline_s = 0.0;       ///< 0: the lab's (lock-step wait for a frame's inputs)
  double status_period_s = 0.5;  ///< ServiceStatus heartbeat period

  void declare(Cli& cli);
};

/// Median and p99 of a window of values (µs), cleared on read.
struct Window {
  std::vector<double> v;
  void add(double x) { v.push_back(x); }
  double percentile(double p) const;
};

class Service {
 public:
  /// Loads and checks the lab and the options; any failure: cli.fail (exit 2). No DDS yet, so
  /// that a main can check the rest of its configuration before any participant exists (a
  /// participant alive at exit() would leave its shared-memory segment behind).
  /// steps = false (the ingest): the service steps nothing, so it needs no frame rate (a lab
  /// without a recording does not make --frame-rate required).
  Service(std::string name, const CommonOptions& options, const Cli& cli, bool steps = true);
  ~Service();
  /// Makes the participant and the status writer; failure: cli.fail (exit 2).
  void connect();
  /// For configuration errors found after connect(): destroys the participant, then cli.fail.
  [[noreturn]] void fail(const std::string& reason);

  const std::string& name() const { return name_; }
  const LabConfig& lab() const { return lab_; }
  const CommonOptions& options() const { return opt_; }
  dds::Participant& dds() { return *participant_; }
  bool lockstep() const { return opt_.lockstep; }
  /// Profiles: pose streams (best-effort live, reliable lock-step), states (transient local).
  const char* streamProfile() const;
  const char* stateProfile() const;
  std::string sceneFile() const { return opt_.scene.empty() ? lab_.scene : opt_.scene; }
  double frameRate() const { return frame_rate_; }
  double deadlineSeconds() const;
  double staleAfterSeconds() const { return lab_.stale_after_s; }

  // Counters (printed by finish(), sent with every heartbeat).
  std::uint64_t samples_in = 0, samples_out = 0, late = 0, deadline_misses = 0;
  void reject(const std::string& reason);  ///< one rejected input, by reason (first few logged)
  std::uint64_t rejected() const;
  /// The ingest: its tracker source's counts and the run they belong to, sent with every heartbeat
  /// (ServiceStatus.source; without a provider, run 0: no source).
  void sourceCounts(std::uint64_t run, std::function<SourceCounts()> provider);
  /// A frame done: its source time (for the latency window).
  void processed(std::uint64_t frame, std::int64_t source_time_ns);

  /// Publishes a heartbeat when the period has passed (or now with force).
  void heartbeat(const std::string& state = "running", bool force = false);
  /// Waits for data on any reader until `until`, keeping heartbeats going. Returns false when a
  /// stop was requested (SIGINT/SIGTERM), true otherwise (data or timeout).
  bool wait(SteadyClock::time_point until, const std::string& state = "running");
  bool stopping() const;
  /// Prints the counters (one block on stderr), sends a last "stopping" heartbeat, returns code.
  int finish(int code, const std::string& why = "");

 private:
  std::string name_;
  CommonOptions opt_;
  const Cli& cli_;
  LabConfig lab_;
  double frame_rate_ = 0.0;
  std::unique_ptr<dds::Participant> participant_;
  std::unique_ptr<dds::Writer<msg::ServiceStatus>> status_;
  std::map<std::string, std::uint64_t> rejects_;
  std::uint64_t source_run_ = 0;
  std::function<SourceCounts()> source_counts_;
  std::uint64_t frame_ = 0, frames_since_ = 0;
  Window latency_;
  double last_latency_us_ = 0.0;
  SteadyClock::time_point last_beat_{};
  SteadyClock::time_point started_;
};

/// The frame rate of a tracker recording (for services that are not given --frame-rate).
double recordingFrameRate(const std::string& recording);

}  // namespace godhand::svc
