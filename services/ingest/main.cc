// godhand-ingest: reads one tracker source (bridges/source) and publishes one HandTarget per
// hand cluster of the lab and frame. Live: replays a recording at the recorded rate (times
// --speed), or publishes each frame of a live source (dtrack://HOST:PORT) as it arrives.
// Lock-step: publishes frame k once every cluster's HandState of frame k-1 is back, so the run
// goes as fast as the slowest stage allows and is deterministic.
#include <malloc.h>
#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <map>
#include <thread>

#include "common/files.h"
#include "leap/retarget.h"
#include "leap/tool_target.h"
#include "model/hand_model.h"
#include "runtime/lab_checks.h"
#include "runtime/convert.h"
#include "runtime/service.h"
#include "source/live.h"
#include "source/recording.h"
#include "source/tracker_source.h"

using namespace godhand;
using svc::SteadyClock;

namespace {
constexpr const char* kSynopsis =
    "Reads a tracker source and publishes godhand/hand_target: per frame one HandTarget for each hand\n"
    "cluster of the lab (the tracked hand of the cluster's side with the highest confidence,\n"
    "retargeted onto the cluster's hand model; tracked = false when the side is not seen); a tool\n"
    "cluster (tracker_body N, a model with tracker_segment \"tool\") takes the pose of 6-DOF body N.\n"
    "Live mode replays at the recorded rate; --lockstep waits for each frame's HandStates.\n"
    "A live source (dtrack://HOST:PORT: ART DTrack ASCII over UDP) publishes every accepted frame as\n"
    "it arrives, reports a silence of --silence S seconds (and publishes the hands untracked, so\n"
    "they are held), and runs until --duration S or SIGINT/SIGTERM.";
}

int main(int argc, char** argv) {
  Cli cli("godhand-ingest", kSynopsis);
  svc::CommonOptions common;
  common.declare(cli);
  std::string source_spec;
  int frames = 0;
  double speed = 1.0, start_timeout = 30.0;
  cli.option("--source", &source_spec, "SPEC",
             "tracker source: a recording of any format (Leap JSON, .dtrack, OpenXR / MediaPipe JSON Lines, Aria CSV,\n"
             "a synthetic script, a --record file; detected by content: bridges/README.md),\n"
             "leap:FILE / dtrack:FILE, or a live dtrack://HOST:PORT (default: the lab's recording)");
  double duration = 0.0, silence = 1.0;
  std::string record;
  bridges::CalibrationText calib;
  cli.option("--duration", &duration, "S", "stop cleanly after S seconds (0: at the end of a recording / never for a live source)");
  cli.option("--silence", &silence, "S", "a live source without frames for S seconds is reported (default 1)");
  cli.option("--record", &record, "FILE", "live source: write every datagram that comes in, with its arrival time (replayable)");
  cli.option("--tracker-pose", &calib.pose, "POSE", "tracker to world: x,y,z[,rx,ry,rz degrees | ,qw,qx,qy,qz] (m)");
  cli.option("--tracker-units", &calib.units, "U", "DTrack room units: mm (default), cm, m");
  cli.option("--tracker-up", &calib.up, "AXIS", "DTrack room up axis: z (default, normal calibration) or y (powerwall)");
  cli.option("--hand-map", &calib.hand_map, "MAP", "tracker hand id -> side, e.g. 0:left,1:right (others dropped, counted)");
  cli.option("--palm-offset", &calib.palm_offset, "F,T,P", "DTrack: palm centre from the hand target, m (toward fingers, thumb, palm)");
  cli.option("--max-datagram", &calib.max_datagram, "BYTES", "DTrack: larger datagrams are rejected as oversized (default 32768)");
  cli.option("--tracking-volume", &calib.volume_m, "M", "hands with a coordinate beyond M metres of the tracker (its frame) are dropped, counted (0: 50 m)");
  cli.option("--max-speed", &calib.max_speed, "MPS", "palm jumps faster than this are dropped, counted (0: 30 m/s)");
  cli.option("--frames", &frames, "N", "stop after N frames (0: all)");
  cli.option("--speed", &speed, "X", "live replay speed factor");
  cli.option("--start-timeout", &start_timeout, "S", "wait at most this long for every service of the lab to report");
  int readers = 0;
  cli.option("--readers", &readers, "N", "start once N HandTarget readers are matched (0: one per cluster; godhand-launch adds its monitor)");
  cli.parse(argc, argv);
  if (frames < 0) cli.fail("--frames must be >= 0");
  if (!(speed >= 0.01 && speed <= 1000.0)) cli.fail("--speed must be in [0.01, 1000]");
  if (!(start_timeout > 0.0 && start_timeout <= 3600.0)) cli.fail("--start-timeout must be in (0, 3600] s");
  if (readers < 0 || readers > 1000) cli.fail("--readers must be in [0, 1000]");
  if (!(duration >= 0.0 && duration <= 7 * 86400.0)) cli.fail("--duration must be in [0, 604800] s");
  if (!(silence >= 0.05 && silence <= 3600.0)) cli.fail("--silence must be in [0.05, 3600] s");

  svc::Service service("ingest", common, cli, /*steps=*/false);
  const LabConfig& lab = service.lab();
  // The lab's tracker calibration, where the command line left a field at its default.
  if (lab.tracker.any()) {
    bridges::CalibrationText from_lab;
    try {
      from_lab = svc::labCalibration(lab);
    } catch (const std::exception& e) {
      cli.fail(e.what());
    }
    if (calib.pose.empty()) calib.pose = from_lab.pose;
    if (calib.units.empty()) calib.units = from_lab.units;
    if (calib.up.empty()) calib.up = from_lab.up;
    if (calib.hand_map.empty()) calib.hand_map = from_lab.hand_map;
    if (calib.palm_offset.empty()) calib.palm_offset = from_lab.palm_offset;
    if (calib.volume_m == 0.0) calib.volume_m = from_lab.volume_m;
    if (calib.max_speed == 0.0) calib.max_speed = from_lab.max_speed;
  }
  if (source_spec.empty()) source_spec = lab.recording;
  if (source_spec.empty()) cli.fail("no tracker source: give --source or a recording in the lab");
  std::unique_ptr<bridges::TrackerSource> source;
  std::vector<HandModel> models(lab.clusters.size());
  std::vector<std::unique_ptr<leap::Retargeter>> retarget;
  try {
    source = bridges::openSource(source_spec, bridges::sourceOptions(calib, frames));
    ::malloc_trim(0);  // a recording's JSON document is freed by now: give its pages back (glibc keeps them)
    if (!source->live()) {
      // (Live, the services step at the replay's wall-clock rate: the recording's times --speed.)
      const std::string mismatch =
          svc::replayRateMismatch(common.frame_rate, source->nominalRate(), service.lockstep() ? 1.0 : speed, source_spec);
      if (!mismatch.empty()) cli.fail(mismatch);
    }
    if (source->live()) {
      if (service.lockstep()) cli.fail("--lockstep needs a recording, not a live source (" + source_spec + ")");
      source->start();  // bind now: a port in use is a configuration error
    } else if (!record.empty()) {
      cli.fail("--record needs a live source (a recording is already a file)");
    }
    for (size_t c = 0; c < lab.clusters.size(); ++c) {
      models[c] = loadHandModel(lab.clusters[c].model);
      retarget.push_back(svc::clusterRetargeter(lab.clusters[c], models[c]));  // nullptr: a tool cluster
    }
  } catch (const std::exception& e) {
    cli.fail(e.what());
  }
  std::unique_ptr<bridges::RawWriter> recorder;
  if (!record.empty()) {
    try {
      recorder = std::make_unique<bridges::RawWriter>(record, "dtrack");
    } catch (const std::exception& e) {
      cli.fail(e.what());
    }
    source->setTap([&recorder](const std::string& bytes, std::int64_t arrival_ns) { recorder->write(bytes, arrival_ns); });
  }
  std::fprintf(stderr, "ingest: %s -> %zu cluster(s), %s mode, domain %d\n", source->describe().c_str(),
               lab.clusters.size(), service.lockstep() ? "lock-step" : "live", common.domain >= 0 ? common.domain : static_cast<int>(lab.domain_id));
  // Hands of a side that no cluster of the lab drives are published nowhere: said at the start
  // (a recording's sides are known), counted at the end (every source).
  bool side_driven[2] = {false, false};
  for (size_t c = 0; c < lab.clusters.size(); ++c)
    if (retarget[c]) side_driven[lab.clusters[c].side == "right" ? 1 : 0] = true;
  std::uint64_t undriven[2] = {0, 0};
  if (!source->live())
    for (const bool right : {false, true})
      if (source->hasSide(right) && !side_driven[right ? 1 : 0])
        std::fprintf(stderr, "ingest: the source has %s hands and the lab no %s cluster: they drive nothing\n",
                     right ? "right" : "left", right ? "right" : "left");

  service.connect();
  std::unique_ptr<dds::Writer<msg::HandTarget>> writer_p;
  std::unique_ptr<dds::Reader<msg::HandState>> states_p;
  std::unique_ptr<dds::Reader<msg::ServiceStatus>> statuses_p;
  try {
    writer_p = std::make_unique<dds::Writer<msg::HandTarget>>(service.dds(), dds::topic::kHandTarget, service.streamProfile());
    states_p = std::make_unique<dds::Reader<msg::HandState>>(service.dds(), dds::topic::kHandState, service.stateProfile());
    statuses_p = std::make_unique<dds::Reader<msg::ServiceStatus>>(service.dds(), dds::topic::kServiceStatus, dds::profile::kStatus);
  } catch (const std::exception& e) {
    service.fail(e.what());
  }
  auto& writer = *writer_p;
  auto& states = *states_p;
  auto& statuses = *statuses_p;

  // Start barrier: every service of the lab has reported (so no frame is published into the void).
  std::vector<std::string> expected;
  for (const LabService& s : lab.services)
    if (s.kind != pb::Service::INGEST) expected.push_back(s.name);
  {
    std::map<std::string, bool> seen;
    const auto until = SteadyClock::now() + std::chrono::duration_cast<SteadyClock::duration>(std::chrono::duration<double>(start_timeout));
    msg::ServiceStatus st;
    for (;;) {
      while (statuses.take(st))
        if (st.state() == "running") seen[st.service().to_string()] = true;
      size_t ready = 0;
      for (const std::string& e : expected) ready += seen.count(e);
      const int want = std::max(readers, static_cast<int>(lab.clusters.size()));
      if (ready == expected.size() && writer.matched() >= want) break;
      if (SteadyClock::now() >= until) {
        std::string missing;
        for (const std::string& e : expected)
          if (!seen.count(e)) missing += (missing.empty() ? "" : ", ") + e;
        if (missing.empty()) missing = std::to_string(writer.matched()) + " of " + std::to_string(std::max(readers, static_cast<int>(lab.clusters.size()))) + " HandTarget readers matched";
        // Lock-step needs every stage; live degrades (the missing ones are held when they come).
        if (service.lockstep())
          return service.finish(3, "services not running after " + std::to_string(start_timeout) + " s: " + missing);
        std::fprintf(stderr, "ingest: live: starting without %s (not running after %g s)\n", missing.c_str(), start_timeout);
        break;
      }
      if (!service.wait(std::min(until, SteadyClock::now() + std::chrono::milliseconds(50)), "waiting")) return service.finish(0);
    }
  }

  const size_t C = lab.clusters.size();
  std::vector<std::uint64_t> resolved(C, 0);  // newest HandState frame per cluster
  std::vector<Pose> targets;
  std::vector<unsigned char> driven;
  msg::HandTarget out;
  msg::HandState hs;
  bridges::TrackerFrame f;
  std::int64_t t0_us = 0;
  SteadyClock::time_point t0;
  std::uint64_t k = 0;
  const double deadline = service.deadlineSeconds();
  const std::uint64_t run = static_cast<std::uint64_t>(svc::nowNs());  // this run's identity on the wire
  auto drainStates = [&] {
    while (states.take(hs)) {  // only this run's states count (a previous run's are transient-local history)
      if (hs.hand() < C && hs.stamp().run() == run) resolved[hs.hand()] = std::max(resolved[hs.hand()], hs.stamp().frame());
    }
  };
  auto waitResolved = [&](std::uint64_t frame) -> int {  // 0 ok, 1 stop, 2 deadline
    const auto until = SteadyClock::now() + std::chrono::duration_cast<SteadyClock::duration>(std::chrono::duration<double>(deadline));
    for (;;) {
      drainStates();
      bool all = true;
      for (size_t c = 0; c < C; ++c) all = all && resolved[c] >= frame;
      if (all) return 0;
      if (SteadyClock::now() >= until) return 2;
      if (!service.wait(until)) return 1;
    }
  };
  const bool live_source = source->live();
  const SteadyClock::time_point run_start = SteadyClock::now();
  auto elapsed = [&] { return std::chrono::duration<double>(SteadyClock::now() - run_start).count(); };
  bridges::SilenceMonitor silence_monitor(silence);
  bridges::TrackerFrame f_newer;
  std::uint64_t superseded = 0;
  if (live_source) std::fprintf(stderr, "ingest: live source %s: receiving\n", source_spec.c_str());
  std::map<std::string, std::uint64_t> source_rejects;  // reasons already passed to service.reject
  auto syncRejects = [&] {
    for (const auto& [reason, n] : reasonMap(source->stats().by_reason))
      for (std::uint64_t& have = source_rejects[reason]; have < n; ++have) service.reject("source: " + reason);
  };
  // Every heartbeat from here carries the source's counts of this run (the launch report's
  // `source`, summed there over ingest runs). A recording's frames not played are not received:
  // counted apart, by reason (kNotPlayedYet while it plays; a killed run's last heartbeat keeps it).
  std::string end_reason;  // why the run stops before the end of the recording, when it knows
  auto notPlayed = [&](const bridges::SourceStats& ss) {
    std::map<std::string, std::uint64_t> m;
    if (ss.not_played_beyond_limit > 0) m["beyond --frames " + std::to_string(frames)] = ss.not_played_beyond_limit;
    const std::uint64_t rest = ss.not_played - std::min(ss.not_played, ss.not_played_beyond_limit);
    if (rest > 0) {
      m[!end_reason.empty() ? end_reason
        : service.stopping() ? std::string("stopped (SIGINT/SIGTERM)")
        : duration > 0.0 && elapsed() >= duration ? durationReachedReason(duration)
                                                  : std::string(kNotPlayedYet)] = rest;
    }
    return m;
  };
  service.sourceCounts(run, [&source, &notPlayed] {
    const bridges::SourceStats ss = source->stats();
    SourceCounts c;
    c.received = ss.received;
    c.accepted = ss.frames;
    c.rejected = reasonMap(ss.by_reason);
    c.not_played = notPlayed(ss);
    return c;
  });
  auto publishUntracked = [&] {  // a silent source: every cluster's hand untracked (held downstream)
    ++k;
    for (size_t c = 0; c < C; ++c) {
      out.hand(static_cast<std::uint32_t>(c));
      out.cluster(lab.clusters[c].name);
      out.stamp().run(run);
      out.stamp().frame(k);
      out.stamp().source_time_ns(svc::nowNs());
      out.tracked(false);
      out.confidence(0.0f);
      out.targets().clear();
      out.driven().clear();
      out.stamp().publish_time_ns(svc::nowNs());
      if (writer.write(out)) ++service.samples_out;
    }
  };
  // 1: a frame in f, 0: the end (recording over, or --duration), -1: stop requested.
  auto nextFrame = [&]() -> int {
    if (duration > 0.0 && elapsed() >= duration) return 0;
    if (!live_source) {  // a recording: its rejections count as a live source's do (services.ingest.rejected)
      const bool more = source->next(&f);
      syncRejects();
      return more ? 1 : 0;
    }
    for (;;) {
      if (source->next(&f)) {
        // Real time: when several frames queued up (a burst, or the start barrier), only the
        // newest is published; the others are counted as superseded. (For at most 10 ms: a flood
        // of valid datagrams must not keep the ingest from publishing and heartbeats.)
        const auto drain_until = SteadyClock::now() + std::chrono::milliseconds(10);
        while (SteadyClock::now() < drain_until && source->next(&f_newer)) {
          std::swap(f, f_newer);
          ++superseded;
        }
        if (silence_monitor.frame(elapsed()))
          std::fprintf(stderr, "ingest: source %s delivers again after a silence\n", source_spec.c_str());
        syncRejects();
        return 1;
      }
      syncRejects();
      if (service.stopping()) return -1;
      if (duration > 0.0 && elapsed() >= duration) return 0;
      if (silence_monitor.poll(elapsed())) {
        std::fprintf(stderr, "ingest: source %s silent for %.2f s: hands published untracked (held)\n", source_spec.c_str(), silence);
        publishUntracked();
      }
      drainStates();
      service.heartbeat();
      source->waitReadable(20);  // bounded: never blocks heartbeats or a stop
    }
  };
  for (;;) {
    const int got = nextFrame();
    if (got < 0) break;
    if (got == 0) break;
    ++k;
    if (service.lockstep() && k > 1) {
      const int w = waitResolved(k - 1);
      if (w == 1) {
        source->unplay();  // frame k was not published
        return service.finish(0);
      }
      if (w == 2) {
        source->unplay();
        ++service.deadline_misses;
        end_reason = "lock-step deadline missed";
        return service.finish(3, "lock-step: no HandState of frame " + std::to_string(k - 1) + " from every cluster within " +
                                     std::to_string(deadline) + " s");
      }
    }
    if (!service.lockstep() && !live_source) {  // pace at the recorded rate
      if (k == 1) {
        t0_us = f.timestamp_us;
        t0 = SteadyClock::now();
      }
      const auto due = t0 + std::chrono::duration_cast<SteadyClock::duration>(
                                std::chrono::duration<double>(static_cast<double>(f.timestamp_us - t0_us) * 1e-6 / speed));
      while (SteadyClock::now() < due)
        if (!service.wait(due)) {
          source->unplay();  // stopped while pacing: frame k was not published
          return service.finish(0);
        }
      drainStates();
    }
    if (service.stopping()) {
      source->unplay();
      return service.finish(0);
    }
    // Latency is counted from the datagram's arrival for a live source.
    const std::int64_t t_source = live_source && source->lastArrivalNs() > 0 ? source->lastArrivalNs() : svc::nowNs();
    for (size_t c = 0; c < C; ++c) {
      const bridges::TrackedHand* th = retarget[c] ? bridges::handOfSide(f, lab.clusters[c].side == "right") : nullptr;
      double quality = th ? th->confidence : 0.0;
      const bool tool_seen = !retarget[c] && leap::toolTargets(models[c], f, lab.clusters[c].tracker_body, &targets, &driven, &quality);
      out.hand(static_cast<std::uint32_t>(c));
      out.cluster(lab.clusters[c].name);
      out.stamp().run(run);
      out.stamp().frame(k);
      out.stamp().source_time_ns(t_source);
      out.tracked(th != nullptr || tool_seen);
      out.confidence(static_cast<float>(quality));
      out.tracker_time_us(f.timestamp_us);
      out.targets().clear();
      out.driven().clear();
      if (th || tool_seen) {
        if (th) retarget[c]->targets(*th, &targets, &driven);
        out.targets().resize(targets.size());
        for (size_t b = 0; b < targets.size(); ++b) svc::toWire(targets[b], &out.targets()[b]);
        for (unsigned char d : driven) out.driven().push_back(d != 0);
      }
      out.stamp().publish_time_ns(svc::nowNs());
      if (writer.write(out)) ++service.samples_out;
      else service.reject("write failed (hand " + std::to_string(c) + ")");
    }
    for (const bridges::TrackedHand& h : f.hands)
      if (!side_driven[h.right ? 1 : 0]) ++undriven[h.right ? 1 : 0];
    ++service.samples_in;
    service.processed(k, t_source);
    service.heartbeat();
  }
  // The end: lock-step waits for the last frame to come back.
  if (service.lockstep() && k > 0) {
    const int w = waitResolved(k);
    if (w == 2) {
      ++service.deadline_misses;
      end_reason = "lock-step deadline missed";
      return service.finish(3, "lock-step: no HandState of the last frame " + std::to_string(k) + " within the deadline");
    }
  }
  syncRejects();
  const bridges::SourceStats ss = source->stats();
  std::fprintf(stderr, "ingest: source done: %llu frames; %s\n", static_cast<unsigned long long>(ss.frames), ss.detail.c_str());
  if (undriven[0] + undriven[1] > 0)
    std::fprintf(stderr, "ingest: hands of a side no cluster drives (published nowhere): left %llu, right %llu\n",
                 static_cast<unsigned long long>(undriven[0]), static_cast<unsigned long long>(undriven[1]));
  std::string by_reason;
  for (const auto& [reason, n] : ss.by_reason) by_reason += (by_reason.empty() ? "" : ", ") + reason + " " + std::to_string(n);
  std::string not_played;
  for (const auto& [reason, n] : notPlayed(ss)) not_played += (not_played.empty() ? "" : ", ") + reason + " " + std::to_string(n);
  std::fprintf(stderr, "ingest: source %s: received %llu, accepted %llu, rejected %llu (%s), superseded %llu, silences %llu%s%s%s\n",
               source_spec.c_str(), static_cast<unsigned long long>(ss.received), static_cast<unsigned long long>(ss.frames),
               static_cast<unsigned long long>(ss.rejected), by_reason.empty() ? "none" : by_reason.c_str(),
               static_cast<unsigned long long>(superseded), static_cast<unsigned long long>(silence_monitor.silences()),
               not_played.empty() ? "" : ", not played (", not_played.c_str(), not_played.empty() ? "" : ")");
  if (recorder) {
    std::fprintf(stderr, "ingest: recorded %llu datagrams to %s%s\n", static_cast<unsigned long long>(recorder->records()), record.c_str(),
                 recorder->ok() ? "" : " (WRITE ERRORS: the file is incomplete)");
    recorder.reset();
  }
  service.heartbeat("finished", true);
  return service.finish(0);
}
