#include "runtime/service.h"

#include <unistd.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <thread>

#include "common/signals.h"
#include "math/stats.h"
#include "runtime/convert.h"
#include "source/tracker_source.h"

namespace godhand::svc {

void CommonOptions::declare(Cli& cli) {
  lab = std::string(GODHAND_DEPLOY_DIR) + "/lab/local.pbtxt";
  cli.option("--lab", &lab, "FILE", "lab configuration: clusters, models, scene, recording, services");
  cli.option("--domain", &domain, "N", "DDS domain id 0..232; -1 = the lab's");
  cli.option("--profiles", &profiles, "FILE", "Fast DDS XML profiles (default: the lab's, else deploy/dds/godhand-local.xml)");
  cli.flag("--lockstep", &lockstep, "lock-step mode: wait (with a deadline) for every input of each frame; deterministic");
  cli.option("--scene", &scene, "FILE", "scene file (default: the lab's)");
  cli.option("--frame-rate", &frame_rate, "HZ", "tracker frame rate; 0 = the lab recording's mean rate");
  cli.option("--deadline", &deadline_s, "S", "lock-step: seconds to wait for a frame's remaining inputs; 0 = the lab's");
  cli.option("--status-period", &status_period_s, "S", "ServiceStatus heartbeat period");
}

double Window::percentile(double p) const { return godhand::percentile(v, p); }

double recordingFrameRate(const std::string& recording) {
  return bridges::openSource(recording)->nominalRate();
}

Service::Service(std::string name, const CommonOptions& options, const Cli& cli, bool steps)
    : name_(std::move(name)), opt_(options), cli_(cli), started_(SteadyClock::now()) {
  lineBufferedStdout();  // a line printed before a kill is in the log (godhand-launch reads it)
  installStopHandlers();
  try {
    lab_ = loadLab(opt_.lab);
  } catch (const std::exception& e) {
    cli.fail(e.what());
  }
  if (opt_.domain < -1 || opt_.domain > 232) cli.fail("--domain must be in 0..232");
  if (!(opt_.deadline_s >= 0.0 && opt_.deadline_s <= 3600.0)) cli.fail("--deadline must be in [0, 3600] s");
  if (lab_.deadline_s > 3600.0) cli.fail(lab_.file + ": deadline_s must be <= 3600 s");
  if (lab_.stale_after_s > 3600.0) cli.fail(lab_.file + ": stale_after_s must be <= 3600 s");
  if (!(opt_.status_period_s > 0.0 && opt_.status_period_s < 60.0)) cli.fail("--status-period must be in (0, 60) s");
  if (!(opt_.frame_rate >= 0.0 && opt_.frame_rate <= 20000.0)) cli.fail("--frame-rate must be in (0, 20000] Hz");
  frame_rate_ = opt_.frame_rate;
  if (frame_rate_ == 0.0 && steps) {  // (the ingest steps nothing: it need not read the lab's recording)
    if (lab_.recording.empty()) cli.fail("--frame-rate is required: the lab names no recording");
    try {
      frame_rate_ = recordingFrameRate(lab_.recording);
    } catch (const std::exception& e) {
      cli.fail(e.what());
    }
  }
}

void Service::connect() {
  dds::Options o;
  o.domain = opt_.domain >= 0 ? opt_.domain : lab_.domain_id;
  o.profiles = !opt_.profiles.empty() ? opt_.profiles : lab_.profiles;
  o.name = name_;
  try {
    participant_ = std::make_unique<dds::Participant>(o);
    status_ = std::make_unique<dds::Writer<msg::ServiceStatus>>(*participant_, dds::topic::kServiceStatus,
                                                                 dds::profile::kStatus);
  } catch (const std::exception& e) {
    fail(e.what());
  }
  heartbeat("starting", true);
}

void Service::fail(const std::string& reason) {
  status_.reset();
  participant_.reset();
  cli_.fail(reason);
}

Service::~Service() = default;

const char* Service::streamProfile() const { return opt_.lockstep ? dds::profile::kLockStep : dds::profile::kStreamLive; }
const char* Service::stateProfile() const { return opt_.lockstep ? dds::profile::kLockStep : dds::profile::kState; }
double Service::deadlineSeconds() const { return opt_.deadline_s > 0.0 ? opt_.deadline_s : lab_.deadline_s; }

void Service::reject(const std::string& reason) {
  // Bounded: a reason is a fixed text, but a hostile stream could still bring many (each logged
  // three times): past kMaxReasons the rest are counted together.
  constexpr std::size_t kMaxReasons = 32;
  const bool known = rejects_.count(reason) != 0;
  const std::uint64_t n = ++rejects_[known || rejects_.size() < kMaxReasons ? reason : std::string("other reasons")];
  if (n <= 3) std::fprintf(stderr, "%s: rejected input: %s%s\n", name_.c_str(), reason.c_str(), n == 3 ? " (further ones counted only)" : "");
}

std::uint64_t Service::rejected() const {
  std::uint64_t n = participant_ ? participant_->samplesMalformed() : 0;  // dropped by the readers
  for (const auto& r : rejects_) n += r.second;
  return n;
}

void Service::sourceCounts(std::uint64_t run, std::function<SourceCounts()> provider) {
  source_run_ = run;
  source_counts_ = std::move(provider);
}

void Service::processed(std::uint64_t frame, std::int64_t source_time_ns) {
  frame_ = frame;
  ++frames_since_;
  if (source_time_ns > 0) latency_.add(static_cast<double>(nowNs() - source_time_ns) * 1e-3);
}

void Service::heartbeat(const std::string& state, bool force) {
  const SteadyClock::time_point now = SteadyClock::now();
  const double since = std::chrono::duration<double>(now - last_beat_).count();
  if (!force && since < opt_.status_period_s) return;
  msg::ServiceStatus s;
  s.service(name_);
  char host[64] = {0};
  gethostname(host, sizeof host - 1);
  s.host(host);
  s.pid(static_cast<std::int32_t>(getpid()));
  s.time_ns(nowNs());
  s.state(state);
  s.frame(frame_);
  s.rate_hz(last_beat_ == SteadyClock::time_point{} || since <= 0.0 ? 0.0 : static_cast<double>(frames_since_) / since);
  if (!latency_.v.empty()) last_latency_us_ = latency_.percentile(0.5);  // an idle window keeps the last figure
  s.latency_median_us(last_latency_us_);
  s.samples_in(samples_in);
  s.samples_out(samples_out);
  s.rejected(rejected());
  s.late(late);
  s.deadline_misses(deadline_misses);
  if (!status_) return;
  if (source_counts_) toWire(source_run_, source_counts_(), &s.source());
  status_->write(s);
  frames_since_ = 0;
  latency_.v.clear();
  last_beat_ = now;
}

bool Service::stopping() const { return stopRequested(); }

bool Service::wait(SteadyClock::time_point until, const std::string& state) {
  for (;;) {
    if (stopRequested()) return false;
    heartbeat(state);
    const SteadyClock::time_point now = SteadyClock::now();
    if (now >= until) return true;
    // Short slices: stop requests are polled, heartbeats keep going while idle.
    const SteadyClock::time_point slice = std::min(until, now + std::chrono::milliseconds(20));
    if (!participant_) std::this_thread::sleep_until(slice);
    else if (participant_->waitForData(slice)) return !stopRequested();
  }
}

int Service::finish(int code, const std::string& why) {
  const double up = std::chrono::duration<double>(SteadyClock::now() - started_).count();
  if (!why.empty()) std::fprintf(stderr, "%s: %s\n", name_.c_str(), why.c_str());
  std::fprintf(stderr, "%s: %s after %.1f s: frame %llu, samples in %llu, out %llu, rejected %llu, late %llu, deadline misses %llu\n",
               name_.c_str(), stopSignal() ? "stopped by signal" : (code == 0 ? "finished" : "failed"), up,
               static_cast<unsigned long long>(frame_), static_cast<unsigned long long>(samples_in),
               static_cast<unsigned long long>(samples_out), static_cast<unsigned long long>(rejected()),
               static_cast<unsigned long long>(late), static_cast<unsigned long long>(deadline_misses));
  for (const auto& r : rejects_)
    std::fprintf(stderr, "%s:   rejected %llu: %s\n", name_.c_str(), static_cast<unsigned long long>(r.second), r.first.c_str());
  if (participant_ && participant_->samplesMalformed() > 0)
    std::fprintf(stderr, "%s:   rejected %llu: DDS: samples over their IDL bounds or undecodable (dropped by the readers)\n",
                 name_.c_str(), static_cast<unsigned long long>(participant_->samplesMalformed()));
  if (participant_)
    std::fprintf(stderr, "%s:   DDS: samples lost %llu, rejected by the readers' limits %llu\n", name_.c_str(),
                 static_cast<unsigned long long>(participant_->samplesLost()),
                 static_cast<unsigned long long>(participant_->samplesRejected()));
  if (participant_)
    for (const dds::Participant::TopicLosses& t : participant_->lossesByTopic())
      std::fprintf(stderr, "%s:     of them on %s%s: lost %llu, rejected %llu\n", name_.c_str(), t.topic.c_str(),
                   t.newest_only ? " (newest only: superseded by a newer sample before a lost packet was resent)" : "",
                   static_cast<unsigned long long>(t.lost), static_cast<unsigned long long>(t.rejected));
  heartbeat(code == 0 ? "stopping" : "failed", true);
  // The last heartbeat carries the final counters (the launch report's): not lost with the writer
  // when the process exits right after (a short lock-step run had sent only "starting" before).
  if (status_) status_->waitForAcknowledgments(std::chrono::milliseconds(1000));
  // Fault injection for the launcher's tests: a service that never exits after its last
  // heartbeat (GODHAND_FAULT_HANG_AFTER_FINISH names the service). Only SIGKILL ends it.
  if (const char* hang = std::getenv("GODHAND_FAULT_HANG_AFTER_FINISH"); hang != nullptr && name_ == hang) {
    std::fprintf(stderr, "%s: GODHAND_FAULT_HANG_AFTER_FINISH: hanging (fault injection)\n", name_.c_str());
    for (;;) std::this_thread::sleep_for(std::chrono::seconds(1));
  }
  return code;
}

}  // namespace godhand::svc
