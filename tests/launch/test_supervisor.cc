// Process supervision (services/common/supervisor.h). No timed assertions: deadlines are only
// upper bounds for waits. After every test, every child pid the test saw must be gone.
#include <fcntl.h>
#include <gtest/gtest.h>
#include <signal.h>
#include <sys/prctl.h>
#include <sys/stat.h>
#include <sys/wait.h>
#include <unistd.h>

#include <cerrno>
#include <chrono>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <sstream>
#include <string>
#include <thread>
#include <vector>

#include "common/signals.h"
#include "common/supervisor.h"

namespace godhand {
namespace {

namespace fs = std::filesystem;
using std::chrono::milliseconds;
using std::chrono::seconds;

constexpr milliseconds kLong{10000};  // upper bound of every wait

std::string readFile(const std::string& path) {
  std::ifstream in(path);
  std::ostringstream ss;
  ss << in.rdbuf();
  return ss.str();
}

bool pidGone(pid_t pid) { return ::kill(pid, 0) == -1 && errno == ESRCH; }

/// Waits (up to kLong) until `done` holds.
template <class Done>
bool eventually(Done done) {
  const auto deadline = std::chrono::steady_clock::now() + kLong;
  while (!done()) {
    if (std::chrono::steady_clock::now() > deadline) return false;
    std::this_thread::sleep_for(milliseconds(5));
  }
  return true;
}

/// Process state letter from /proc/PID/stat ('S', 'T', 'Z', ...), 0 if gone.
char procState(pid_t pid) {
  const std::string stat = readFile("/proc/" + std::to_string(pid) + "/stat");
  const size_t paren = stat.rfind(')');
  return paren == std::string::npos || paren + 2 >= stat.size() ? 0 : stat[paren + 2];
}

class SupervisorTest : public ::testing::Test {
 protected:
  void SetUp() override {
    dir_ = fs::temp_directory_path() / ("godhand-supervisor-" + std::to_string(::getpid()) + "-" +
                                        ::testing::UnitTest::GetInstance()->current_test_info()->name());
    fs::remove_all(dir_);
    fs::create_directories(dir_);
  }
  void TearDown() override {
    for (pid_t pid : pids_) EXPECT_TRUE(pidGone(pid)) << "child " << pid << " is still there";
    fs::remove_all(dir_);
  }
  /// Remembers the current pid of a child, for the check in TearDown.
  pid_t track(const Supervisor& s, const std::string& name) {
    const ChildStatus* st = s.find(name);
    EXPECT_NE(st, nullptr) << name;
    if (!st) return -1;
    EXPECT_GT(st->pid, 0);
    pids_.push_back(st->pid);
    return st->pid;
  }
  std::string path(const std::string& file) const { return (dir_ / file).string(); }
  /// A child's log contains `text` (within kLong).
  bool logShows(const std::string& log, const std::string& text) {
    return eventually([&] { return readFile(log).find(text) != std::string::npos; });
  }

  fs::path dir_;
  std::vector<pid_t> pids_;
};

ChildSpec sleeper(const std::string& name) { return {name, {"/bin/sleep", "30"}, {}, ""}; }

TEST_F(SupervisorTest, StopTerminatesAndReaps) {
  Supervisor s;
  s.start(sleeper("sleep"));
  const pid_t pid = track(s, "sleep");
  const ChildStatus* st = s.find("sleep");
  ASSERT_NE(st, nullptr);
  EXPECT_EQ(st->name, "sleep");
  EXPECT_TRUE(st->running);
  EXPECT_EQ(st->restarts, 0);
  EXPECT_EQ(::kill(pid, 0), 0);
  EXPECT_TRUE(s.poll().empty());
  s.stop(seconds(2));
  st = s.find("sleep");
  EXPECT_FALSE(st->running);
  EXPECT_FALSE(st->exited);
  EXPECT_EQ(st->term_signal, SIGTERM);
  EXPECT_TRUE(pidGone(pid));
  EXPECT_FALSE(s.signal("sleep", SIGTERM));  // no longer running
  s.stop(seconds(2));                         // nothing left: a no-op
}

// Where a child hangs: every thread's backtrace from gdb, the child still running afterwards (gdb
// detaches). Without gdb on PATH the answer says so in one line; a child that is not running
// has none.
TEST_F(SupervisorTest, BacktracesOfARunningChild) {
  Supervisor s;
  s.start(sleeper("sleep"));
  const pid_t pid = track(s, "sleep");
  EXPECT_EQ(s.backtraces("nobody", seconds(5)), "(no backtrace of nobody: not running)\n");
  const char* old_path = std::getenv("PATH");
  const std::string saved = old_path ? old_path : "";
  ::setenv("PATH", dir_.c_str(), 1);  // an empty directory: no gdb there
  EXPECT_EQ(s.backtraces("sleep", seconds(5)), "(no backtrace of sleep: gdb is not installed)\n");
  ::setenv("PATH", saved.c_str(), 1);
  bool have_gdb = false;
  for (const char* dir : {"/usr/bin", "/bin", "/usr/local/bin"})
    have_gdb = have_gdb || ::access((std::string(dir) + "/gdb").c_str(), X_OK) == 0;
  if (have_gdb) {
    const std::string bt = s.backtraces("sleep", seconds(60));
    if (bt.find("ptrace:") != std::string::npos) {
      // (A container without ptrace: gdb says why, and that is the answer the report shows.)
      std::printf("(gdb may not attach here: %s)\n", bt.substr(0, 200).c_str());
    } else {
      // One thread, its frames numbered from #0, in the sleep the child is in.
      EXPECT_NE(bt.find("#0"), std::string::npos) << bt;
      EXPECT_NE(bt.find("sleep"), std::string::npos) << bt;
    }
    EXPECT_EQ(::kill(pid, 0), 0) << "gdb must leave the child running";
    const ChildStatus* st = s.find("sleep");
    ASSERT_NE(st, nullptr);
    EXPECT_TRUE(st->running);
    EXPECT_TRUE(s.poll().empty());
  } else {
    std::printf("(gdb not installed here: only the answers without it were checked)\n");
  }
  s.stop(seconds(2));
  EXPECT_EQ(s.backtraces("sleep", seconds(5)), "(no backtrace of sleep: not running)\n");
}

TEST_F(SupervisorTest, ExitCodeRecordedByPoll) {
  Supervisor s;
  s.start({"three", {"/bin/sh", "-c", "exit 3"}, {}, ""});
  track(s, "three");
  std::vector<ChildStatus> ended;
  ASSERT_TRUE(eventually([&] {
    ended = s.poll();
    return !ended.empty();
  }));
  ASSERT_EQ(ended.size(), 1u);
  EXPECT_EQ(ended[0].name, "three");
  EXPECT_FALSE(ended[0].running);
  EXPECT_TRUE(ended[0].exited);
  EXPECT_EQ(ended[0].exit_code, 3);
  EXPECT_EQ(ended[0].term_signal, 0);
  EXPECT_TRUE(s.poll().empty());  // reported once
  const std::vector<ChildStatus> all = s.status();
  ASSERT_EQ(all.size(), 1u);
  EXPECT_EQ(all[0].exit_code, 3);
  EXPECT_TRUE(s.waitExit("three", kLong));
}

TEST_F(SupervisorTest, NonexistentExecutableThrowsWithPath) {
  Supervisor s;
  const std::string missing = path("no-such-program");
  try {
    s.start({"ghost", {missing, "--x"}, {}, ""});
    FAIL() << "start did not throw";
  } catch (const std::runtime_error& e) {
    EXPECT_EQ(std::string(e.what()), "ghost: cannot run " + missing + ": No such file or directory");
  }
  EXPECT_TRUE(s.status().empty());
  EXPECT_EQ(s.find("ghost"), nullptr);
  try {
    s.start({"ghost", {"godhand-no-such-program-in-path"}, {}, ""});
    FAIL() << "start did not throw";
  } catch (const std::runtime_error& e) {
    EXPECT_EQ(std::string(e.what()), "ghost: cannot run godhand-no-such-program-in-path: not found in PATH");
  }
  EXPECT_THROW(s.start({"dir", {dir_.string()}, {}, ""}), std::runtime_error);
  EXPECT_THROW(s.start({"empty", {}, {}, ""}), std::runtime_error);
  EXPECT_THROW(s.start({"", {"/bin/true"}, {}, ""}), std::runtime_error);
}

TEST_F(SupervisorTest, NotExecutableFileThrows) {
  const std::string file = path("data.txt");
  std::ofstream(file) << "not a program\n";
  ::chmod(file.c_str(), 0644);
  Supervisor s;
  try {
    s.start({"data", {file}, {}, ""});
    FAIL() << "start did not throw";
  } catch (const std::runtime_error& e) {
    EXPECT_EQ(std::string(e.what()), "data: cannot run " + file + ": Permission denied");
  }
}

TEST_F(SupervisorTest, ExecFailureInTheChildIsReported) {
  // Executable bits but no valid format: passes the checks before fork, execve fails (ENOEXEC)
  // in the child, which reports it through the status pipe.
  const std::string file = path("garbage");
  std::ofstream(file) << std::string("\x7f\x01\x02\x03garbage", 11);
  ::chmod(file.c_str(), 0755);
  Supervisor s;
  try {
    s.start({"garbage", {file}, {}, ""});
    FAIL() << "start did not throw";
  } catch (const std::runtime_error& e) {
    EXPECT_EQ(std::string(e.what()), "garbage: cannot run " + file + ": Exec format error");
  }
  EXPECT_EQ(s.find("garbage"), nullptr);
}

TEST_F(SupervisorTest, PathLookup) {
  Supervisor s;
  s.start({"sleep", {"sleep", "30"}, {}, ""});
  track(s, "sleep");
  EXPECT_TRUE(s.find("sleep")->running);
  s.stop(seconds(2));
}

TEST_F(SupervisorTest, KillAndRestart) {
  Supervisor s;
  s.start(sleeper("sleep"));
  const pid_t first = track(s, "sleep");
  EXPECT_THROW(s.restart("sleep"), std::runtime_error);        // still running
  EXPECT_THROW(s.start(sleeper("sleep")), std::runtime_error);  // same name, still running
  EXPECT_THROW(s.restart("nobody"), std::runtime_error);
  EXPECT_FALSE(s.signal("nobody", SIGKILL));
  ASSERT_TRUE(s.signal("sleep", SIGKILL));
  ASSERT_TRUE(s.waitExit("sleep", kLong));
  EXPECT_FALSE(s.find("sleep")->running);
  EXPECT_EQ(s.find("sleep")->term_signal, SIGKILL);
  EXPECT_TRUE(pidGone(first));

  s.restart("sleep");
  const pid_t second = track(s, "sleep");
  EXPECT_NE(second, first);
  const ChildStatus* st = s.find("sleep");
  EXPECT_TRUE(st->running);
  EXPECT_EQ(st->restarts, 1);
  EXPECT_EQ(st->term_signal, 0);
  EXPECT_EQ(::kill(second, 0), 0);
  EXPECT_FALSE(s.waitExit("sleep", milliseconds(1)));
  s.stop(seconds(2));
  EXPECT_EQ(s.find("sleep")->term_signal, SIGTERM);
  EXPECT_EQ(s.find("sleep")->restarts, 1);
}

TEST_F(SupervisorTest, ChildIgnoringSigtermIsKilledAfterGrace) {
  // `exec` so the TERM-ignoring sleep is the child itself (dash would otherwise fork it as a
  // grandchild, which stop() does not reach: children stay in the launcher's process group).
  const std::string log = path("ignores_term.log");
  Supervisor s;
  s.start({"ignores_term", {"/bin/sh", "-c", "trap '' TERM; echo ready; exec sleep 30"}, {}, log});
  const pid_t pid = track(s, "ignores_term");
  ASSERT_TRUE(logShows(log, "ready"));  // the trap is in place
  s.stop(milliseconds(300));
  const ChildStatus* st = s.find("ignores_term");
  EXPECT_FALSE(st->running);
  EXPECT_EQ(st->term_signal, SIGKILL);
  EXPECT_TRUE(pidGone(pid));
}

TEST_F(SupervisorTest, StoppedChildStillStops) {
  Supervisor s;
  s.start(sleeper("sleep"));
  const pid_t pid = track(s, "sleep");
  ASSERT_TRUE(s.signal("sleep", SIGSTOP));
  ASSERT_TRUE(eventually([&] { return procState(pid) == 'T'; }));
  s.stop(seconds(5));
  EXPECT_EQ(s.find("sleep")->term_signal, SIGTERM);
}

TEST_F(SupervisorTest, WaitAllExit) {
  Supervisor s;
  s.start({"quick", {"/bin/true"}, {}, ""});
  s.start(sleeper("slow"));
  track(s, "quick");
  track(s, "slow");
  EXPECT_TRUE(s.waitExit("quick", kLong));
  EXPECT_TRUE(s.find("quick")->exited);
  EXPECT_EQ(s.find("quick")->exit_code, 0);
  EXPECT_FALSE(s.waitAllExit(milliseconds(20)));
  ASSERT_TRUE(s.signal("slow", SIGTERM));
  EXPECT_TRUE(s.waitAllExit(kLong));
  EXPECT_EQ(s.find("slow")->term_signal, SIGTERM);
  EXPECT_THROW(s.waitExit("nobody", milliseconds(1)), std::runtime_error);
  const std::vector<ChildStatus> all = s.status();
  ASSERT_EQ(all.size(), 2u);
  EXPECT_EQ(all[0].name, "quick");  // start order
  EXPECT_EQ(all[1].name, "slow");
}

TEST_F(SupervisorTest, StartAgainAfterExitReplacesTheSpec) {
  Supervisor s;
  s.start({"job", {"/bin/sh", "-c", "exit 1"}, {}, ""});
  track(s, "job");
  ASSERT_TRUE(s.waitExit("job", kLong));
  s.start({"job", {"/bin/sh", "-c", "exit 4"}, {}, ""});
  track(s, "job");
  ASSERT_TRUE(s.waitExit("job", kLong));
  EXPECT_EQ(s.find("job")->exit_code, 4);
  EXPECT_EQ(s.find("job")->restarts, 1);
  s.restart("job");  // the new spec
  track(s, "job");
  ASSERT_TRUE(s.waitExit("job", kLong));
  EXPECT_EQ(s.find("job")->exit_code, 4);
  EXPECT_EQ(s.find("job")->restarts, 2);
}

TEST_F(SupervisorTest, LogFileGetsStdoutAndStderrAppended) {
  const std::string log = path("child.log");
  const mode_t mask = ::umask(022);
  ::umask(mask);
  Supervisor s;
  const ChildSpec spec{"talk", {"/bin/sh", "-c", "echo to-stdout; echo to-stderr >&2"}, {}, log};
  s.start(spec);
  track(s, "talk");
  ASSERT_TRUE(s.waitExit("talk", kLong));
  EXPECT_EQ(readFile(log), "to-stdout\nto-stderr\n");
  struct stat st;
  ASSERT_EQ(::stat(log.c_str(), &st), 0);
  EXPECT_EQ(st.st_mode & 0777, 0644 & ~mask);
  s.restart("talk");
  track(s, "talk");
  ASSERT_TRUE(s.waitExit("talk", kLong));
  EXPECT_EQ(readFile(log), "to-stdout\nto-stderr\nto-stdout\nto-stderr\n");  // appended

  try {
    s.start({"nolog", {"/bin/true"}, {}, path("no/such/dir/x.log")});
    FAIL() << "start did not throw";
  } catch (const std::runtime_error& e) {
    EXPECT_NE(std::string(e.what()).find("nolog: cannot open log file " + path("no/such/dir/x.log")), std::string::npos)
        << e.what();
  }
}

TEST_F(SupervisorTest, ExtraEnvironment) {
  const std::string log = path("env.log");
  ::setenv("GODHAND_TEST_INHERITED", "inherited", 1);
  ::setenv("GODHAND_TEST_OVERRIDDEN", "old", 1);
  Supervisor s;
  s.start({"env",
           {"/bin/sh", "-c", "echo \"$GODHAND_TEST_INHERITED $GODHAND_TEST_OVERRIDDEN $GODHAND_TEST_EXTRA\""},
           {{"GODHAND_TEST_OVERRIDDEN", "new"}, {"GODHAND_TEST_EXTRA", "extra"}},
           log});
  track(s, "env");
  ASSERT_TRUE(s.waitExit("env", kLong));
  EXPECT_EQ(readFile(log), "inherited new extra\n");
  ::unsetenv("GODHAND_TEST_INHERITED");
  ::unsetenv("GODHAND_TEST_OVERRIDDEN");
}

TEST_F(SupervisorTest, InheritedDescriptorsAreClosed) {
  const int leaked = ::open("/dev/null", O_RDONLY);  // no O_CLOEXEC
  ASSERT_GE(leaked, 3);
  const std::string log = path("fds.log");
  Supervisor s;
  const std::string fd = std::to_string(leaked);
  s.start({"fds", {"/bin/sh", "-c", "if [ -e /proc/$$/fd/" + fd + " ]; then echo open; else echo closed; fi"}, {}, log});
  track(s, "fds");
  ASSERT_TRUE(s.waitExit("fds", kLong));
  ::close(leaked);
  EXPECT_EQ(readFile(log), "closed\n");
}

TEST_F(SupervisorTest, DestructorStopsChildren) {
  pid_t pid;
  {
    Supervisor s;
    s.start(sleeper("sleep"));
    pid = track(s, "sleep");
    EXPECT_EQ(::kill(pid, 0), 0);
  }
  EXPECT_TRUE(pidGone(pid));
}

TEST_F(SupervisorTest, ChildrenGetDefaultSignalDispositions) {
  // In a forked copy of this process (stop handlers are process-wide): with SIGINT/SIGTERM
  // handled and SIGPIPE ignored here, the child starts with neither ignored nor blocked.
  const std::string log = path("sig.log");
  EXPECT_EXIT(
      {
        installStopHandlers();
        sigset_t block;
        sigemptyset(&block);
        sigaddset(&block, SIGUSR1);
        ::sigprocmask(SIG_BLOCK, &block, nullptr);
        Supervisor s;
        // The exec'd grep reads its own status: what the child got (the shell's own mask is
        // not: dash blocks every signal around its forks, and a grep it forked could read that).
        s.start({"sig", {"/bin/sh", "-c", "exec grep -E '^Sig(Ign|Blk)' /proc/self/status"}, {}, log});
        const bool done = s.waitExit("sig", kLong);
        std::fprintf(stderr, "%s%s", done ? "" : "timeout\n", readFile(log).c_str());
        std::_Exit(0);
      },
      ::testing::ExitedWithCode(0), "SigBlk:\t0000000000000000\n");
  // SIGPIPE (13) is bit 0x1000 of SigIgn; shells ignore nothing else here, but only check it.
  const std::string out = readFile(log);
  const size_t at = out.find("SigIgn:\t");
  ASSERT_NE(at, std::string::npos) << out;
  const unsigned long long ignored = std::strtoull(out.c_str() + at + 8, nullptr, 16);
  EXPECT_EQ(ignored & (1ull << (SIGPIPE - 1)), 0u) << out;
  EXPECT_EQ(ignored & (1ull << (SIGTERM - 1)), 0u) << out;
  EXPECT_EQ(ignored & (1ull << (SIGINT - 1)), 0u) << out;
}

TEST_F(SupervisorTest, ChildrenDieWithTheLauncher) {
  // reaper (subreaper, so the orphaned sleep is re-parented to it and it can collect its status)
  //   -> launcher: a Supervisor starts `sleep 30`, reports its pid, then _exit()s without stop()
  //   -> the sleep gets PR_SET_PDEATHSIG's SIGTERM.
  // The reaper reports the sleep's pid and exits 0 if it ended by SIGTERM within 5 s.
  int pid_pipe[2];
  ASSERT_EQ(::pipe(pid_pipe), 0);
  const pid_t reaper = ::fork();
  ASSERT_GE(reaper, 0);
  if (reaper == 0) {
    ::close(pid_pipe[0]);
    if (::prctl(PR_SET_CHILD_SUBREAPER, 1) != 0) std::_Exit(10);
    int inner[2];
    if (::pipe(inner) != 0) std::_Exit(11);
    const pid_t launcher = ::fork();
    if (launcher < 0) std::_Exit(12);
    if (launcher == 0) {
      ::close(inner[0]);
      auto* s = new Supervisor;  // never destroyed: the launcher "crashes"
      try {
        s->start(sleeper("sleep"));
      } catch (...) {
        std::_Exit(13);
      }
      const pid_t child = s->find("sleep")->pid;
      if (::write(inner[1], &child, sizeof child) != sizeof child) std::_Exit(14);
      std::_Exit(0);
    }
    ::close(inner[1]);
    pid_t child = -1;
    if (::read(inner[0], &child, sizeof child) != sizeof child) std::_Exit(15);
    if (::write(pid_pipe[1], &child, sizeof child) != sizeof child) std::_Exit(16);
    int ws;
    if (::waitpid(launcher, &ws, 0) != launcher) std::_Exit(17);
    const auto deadline = std::chrono::steady_clock::now() + seconds(5);
    for (;;) {
      const pid_t r = ::waitpid(child, &ws, WNOHANG);
      if (r == child) std::_Exit(WIFSIGNALED(ws) && WTERMSIG(ws) == SIGTERM ? 0 : 18);
      if (r < 0) std::_Exit(19);
      if (std::chrono::steady_clock::now() > deadline) {
        ::kill(child, SIGKILL);
        ::waitpid(child, &ws, 0);
        std::_Exit(20);  // still alive after 5 s
      }
      std::this_thread::sleep_for(milliseconds(5));
    }
  }
  ::close(pid_pipe[1]);
  pid_t child = -1;
  const bool got_pid = ::read(pid_pipe[0], &child, sizeof child) == sizeof child;
  ::close(pid_pipe[0]);
  int ws = 0;
  ASSERT_EQ(::waitpid(reaper, &ws, 0), reaper);
  ASSERT_TRUE(got_pid);
  pids_.push_back(child);
  ASSERT_TRUE(WIFEXITED(ws));
  EXPECT_EQ(WEXITSTATUS(ws), 0) << "reaper exit code (18: not SIGTERM, 20: sleep survived its launcher)";
  EXPECT_FALSE(fs::exists("/proc/" + std::to_string(child)));
}

}  // namespace
}  // namespace godhand
