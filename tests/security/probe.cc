// godhand-dds-probe: a test participant for the DDS-Security tests (tests/programs/security.py).
// It joins a running lab with the profiles it is given (secured with some identity, or not at
// all) and either reads or tries to inject, until SIGTERM/SIGINT or --seconds:
//   read    subscribes to HandState and HandTarget; prints how many samples of each hand index
//           it received (the lab's clusters are 0, 1, ...; injected samples use --hand)
//   inject  creates HandState and HandTarget writers (each may be refused: access control) and
//           writes samples of hand --hand (cluster "probe") every 20 ms
// Output: "probe read: matched hand_state N hand_target M" whenever the reader's match count
// grows, and one line "probe MODE: key value ..." at the end, e.g. "probe read: hand_state 0:312
// 1:310 hand_target 0:307 matched_max 4"; exit 0 (a refused participant or writer is a result,
// not an error), 2 on bad arguments.
#include <chrono>
#include <cstdio>
#include <map>
#include <memory>
#include <string>

#include "common/cli.h"
#include "common/signals.h"
#include "dds/dds.h"
#include "dds/topics.h"
#include "godhand.h"

using namespace godhand;
using Clock = std::chrono::steady_clock;

int main(int argc, char** argv) {
  Cli cli("godhand-dds-probe", "A test participant: reads a lab's HandState/HandTarget or tries to inject marked samples.");
  std::string mode = "read", profiles;
  int domain = 0;
  double seconds = 60;
  int hand = 63;
  cli.option("--mode", &mode, "read|inject", "what to do");
  cli.option("--profiles", &profiles, "FILE", "Fast DDS profiles (participant profile godhand_participant)");
  cli.option("--domain", &domain, "N", "DDS domain id 0..232");
  cli.option("--seconds", &seconds, "S", "stop after S seconds at the latest");
  cli.option("--hand", &hand, "N", "inject: the hand index of the samples written (default 63)");
  cli.parse(argc, argv);
  if (mode != "read" && mode != "inject") cli.fail("--mode must be read or inject");
  if (domain < 0 || domain > 232) cli.fail("--domain must be in 0..232");
  if (!(seconds > 0 && seconds <= 3600)) cli.fail("--seconds must be in (0, 3600]");
  if (hand < 0 || hand > 1000) cli.fail("--hand must be in 0..1000");
  if (!profiles.empty()) {  // (a refused participant is a result; a missing file is a bad argument)
    std::FILE* f = std::fopen(profiles.c_str(), "rb");
    if (!f) cli.fail("--profiles " + profiles + ": cannot read");
    std::fclose(f);
  }
  installStopHandlers();
  std::unique_ptr<dds::Participant> p;
  try {
    p = std::make_unique<dds::Participant>(dds::Options{domain, profiles, dds::profile::kParticipant, "probe/" + mode});
  } catch (const std::exception& e) {
    std::printf("probe %s: participant refused: %s\n", mode.c_str(), e.what());
    return 0;
  }
  const Clock::time_point until = Clock::now() + std::chrono::duration_cast<Clock::duration>(std::chrono::duration<double>(seconds));
  if (mode == "read") {
    dds::Reader<msg::HandState> hs(*p, dds::topic::kHandState, dds::profile::kState);
    dds::Reader<msg::HandTarget> ht(*p, dds::topic::kHandTarget, dds::profile::kStreamLive);
    std::map<std::uint32_t, long> states, targets;
    int max_matched = 0;
    while (!stopRequested() && Clock::now() < until) {
      p->waitForData(Clock::now() + std::chrono::milliseconds(50));
      msg::HandState h;
      while (hs.take(h)) ++states[h.hand()];
      msg::HandTarget t;
      while (ht.take(t)) ++targets[t.hand()];
      if (hs.matched() + ht.matched() > max_matched) {  // progress, for a test waiting on the handshakes
        std::printf("probe read: matched hand_state %d hand_target %d\n", hs.matched(), ht.matched());
        std::fflush(stdout);
      }
      max_matched = std::max(max_matched, hs.matched() + ht.matched());
    }
    std::string line = "probe read: hand_state";
    for (const auto& [k, n] : states) line += " " + std::to_string(k) + ":" + std::to_string(n);
    line += " hand_target";
    for (const auto& [k, n] : targets) line += " " + std::to_string(k) + ":" + std::to_string(n);
    std::printf("%s matched_max %d rejected %llu\n", line.c_str(), max_matched,
                static_cast<unsigned long long>(hs.rejected() + ht.rejected()));
    return 0;
  }
  std::unique_ptr<dds::Writer<msg::HandState>> hs;
  std::unique_ptr<dds::Writer<msg::HandTarget>> ht;
  std::string refused;
  try {
    hs = std::make_unique<dds::Writer<msg::HandState>>(*p, dds::topic::kHandState, dds::profile::kState);
  } catch (const std::exception& e) {
    refused += " hand_state";
    std::fprintf(stderr, "probe inject: HandState writer refused: %s\n", e.what());
  }
  try {
    ht = std::make_unique<dds::Writer<msg::HandTarget>>(*p, dds::topic::kHandTarget, dds::profile::kStreamLive);
  } catch (const std::exception& e) {
    refused += " hand_target";
    std::fprintf(stderr, "probe inject: HandTarget writer refused: %s\n", e.what());
  }
  long written = 0;
  int max_matched = 0;
  for (std::uint64_t k = 1; !stopRequested() && Clock::now() < until; ++k) {
    if (hs) {
      msg::HandState h;
      h.hand(static_cast<std::uint32_t>(hand));
      h.cluster("probe");
      h.stamp().frame(k);
      written += hs->write(h) ? 1 : 0;
      max_matched = std::max(max_matched, hs->matched());
    }
    if (ht) {
      msg::HandTarget t;
      t.hand(static_cast<std::uint32_t>(hand));
      t.stamp().frame(k);
      written += ht->write(t) ? 1 : 0;
      max_matched = std::max(max_matched, ht->matched());
    }
    waitForStop(std::chrono::milliseconds(20));
  }
  std::printf("probe inject: written %ld refused%s matched_max %d\n", written, refused.empty() ? " none" : refused.c_str(), max_matched);
  return 0;
}
