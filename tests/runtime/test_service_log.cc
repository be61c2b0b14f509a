// A service's log keeps every line it printed before a SIGKILL (a fault drill, the watchdog):
// godhand-launch sends a service's stdout and stderr to one file, where stdout would be
// block-buffered and a kill would throw the buffer away (common/signals.h lineBufferedStdout,
// called by svc::Service). The program (tests/runtime/service_prints.cc) is started as the
// launcher starts a service (Supervisor, log file), prints a line to stdout, says it is ready, and
// is killed. The control, a program not set up as a service, loses its line: the test can fail.
#include <gtest/gtest.h>
#include <signal.h>
#include <unistd.h>

#include <chrono>
#include <cstdio>
#include <fstream>
#include <sstream>
#include <string>
#include <thread>

#include "common/supervisor.h"

namespace godhand {
namespace {

std::string readFile(const std::string& path) {
  std::ifstream in(path);
  std::ostringstream ss;
  ss << in.rdbuf();
  return ss.str();
}

/// The log of the program in `mode`, SIGKILLed once it said it printed its line.
std::string logAfterKill(const std::string& mode) {
  const char* t = std::getenv("TMPDIR");
  const std::string base = std::string(t ? t : "/tmp") + "/godhand-service-log-" + std::to_string(::getpid()) + "-" + mode;
  const std::string log = base + ".log", ready = base + ".ready";
  std::remove(log.c_str());
  std::remove(ready.c_str());
  Supervisor sup;
  ChildSpec c;
  c.name = "printer";
  c.argv = {GODHAND_TEST_SERVICE_PRINTS, mode, ready};
  c.log_file = log;
  sup.start(c);
  const auto deadline = std::chrono::steady_clock::now() + std::chrono::seconds(20);
  while (!std::ifstream(ready) && std::chrono::steady_clock::now() < deadline && sup.find("printer")->running) {
    sup.poll();
    std::this_thread::sleep_for(std::chrono::milliseconds(10));
  }
  EXPECT_TRUE(std::ifstream(ready).good()) << mode << ": the program did not get to its line; log:\n" << readFile(log);
  EXPECT_TRUE(sup.signal("printer", SIGKILL));
  EXPECT_TRUE(sup.waitExit("printer", std::chrono::milliseconds(10000)));
  const ChildStatus* st = sup.find("printer");
  EXPECT_TRUE(st && !st->running && !st->exited && st->term_signal == SIGKILL);
  const std::string text = readFile(log);
  std::remove(log.c_str());
  std::remove(ready.c_str());
  return text;
}

TEST(ServiceLog, ALinePrintedBeforeAKillIsInTheLog) {
  EXPECT_NE(logAfterKill("service").find("a line printed before the kill\n"), std::string::npos);
}

TEST(ServiceLog, ControlAProgramNotSetUpAsAServiceLosesItsLine) {
  // stdout to a file is block-buffered: what this test guards against is real.
  EXPECT_EQ(logAfterKill("plain").find("a line printed before the kill"), std::string::npos);
}

}  // namespace
}  // namespace godhand
