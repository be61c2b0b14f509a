// Stop signals (services/common/signals.h). The handlers are process-wide, so every check runs
// in a forked child (death-test style) and reports through its exit status.
#include <gtest/gtest.h>
#include <signal.h>
#include <unistd.h>

#include <cerrno>
#include <chrono>
#include <cstdio>
#include <cstdlib>

#include "common/signals.h"

namespace godhand {
namespace {

using std::chrono::milliseconds;

/// In the child: exit 1 with a message unless `ok`.
void check(bool ok, const char* what) {
  if (!ok) {
    std::fprintf(stderr, "check failed: %s\n", what);
    std::_Exit(1);
  }
}

TEST(SignalsDeathTest, SigtermSetsTheFlagAndIsRemembered) {
  EXPECT_EXIT(
      {
        installStopHandlers();
        installStopHandlers();  // idempotent
        check(!stopRequested(), "no stop before a signal");
        check(stopSignal() == 0, "no signal yet");
        ::raise(SIGTERM);
        check(stopRequested(), "SIGTERM requests a stop");
        check(stopSignal() == SIGTERM, "stopSignal() is SIGTERM");
        ::raise(SIGINT);  // the process survives, the first signal is kept
        check(stopSignal() == SIGTERM, "the first signal is kept");
        std::fprintf(stderr, "survived\n");
        std::_Exit(0);
      },
      ::testing::ExitedWithCode(0), "^survived\n$");
}

TEST(SignalsDeathTest, SigintSetsTheFlag) {
  EXPECT_EXIT(
      {
        installStopHandlers();
        ::kill(::getpid(), SIGINT);
        check(waitForStop(milliseconds(10000)), "SIGINT requests a stop");
        check(stopSignal() == SIGINT, "stopSignal() is SIGINT");
        std::_Exit(0);
      },
      ::testing::ExitedWithCode(0), "");
}

TEST(SignalsDeathTest, SigpipeIsIgnored) {
  EXPECT_EXIT(
      {
        installStopHandlers();
        int fds[2];
        check(::pipe(fds) == 0, "pipe");
        ::close(fds[0]);
        const char c = 'x';
        const ssize_t w = ::write(fds[1], &c, 1);
        check(w == -1 && errno == EPIPE, "write to a closed pipe fails with EPIPE");
        check(!stopRequested(), "SIGPIPE is no stop request");
        std::_Exit(0);
      },
      ::testing::ExitedWithCode(0), "");
}

TEST(SignalsDeathTest, RequestStopAndWaitForStop) {
  EXPECT_EXIT(
      {
        check(!waitForStop(milliseconds(20)), "no stop: waitForStop times out");
        check(!waitForStop(milliseconds(0)), "zero timeout");
        requestStop();
        check(stopRequested(), "requestStop() requests a stop");
        check(stopSignal() == 0, "requestStop() sets no signal");
        check(waitForStop(milliseconds(600000)), "waitForStop returns at once after a stop");
        std::_Exit(0);
      },
      ::testing::ExitedWithCode(0), "");
}

TEST(SignalsDeathTest, WithoutHandlersSigtermStillKills) {
  EXPECT_EXIT(::raise(SIGTERM), ::testing::KilledBySignal(SIGTERM), "");
}

}  // namespace
}  // namespace godhand
