// Process supervision for godhand-launch: start the services of a lab as child processes, watch
// them, restart them, and stop them all, never leaving a process behind.
//
// Guarantees and choices:
//  - start() checks the executable before forking (exists, regular file, executable; a name
//    without '/' is looked up in PATH) and reports a failing exec from the child through a
//    close-on-exec pipe, so a child that cannot run is an exception at start(), with one line
//    "NAME: cannot run PATH: reason", never a silent exit 127.
//  - Children stay in the launcher's process group (no setsid/setpgid). A Ctrl-C in the terminal
//    (or `kill -INT -PGID`, or systemd's control-group kill) therefore reaches every service at
//    once and each shuts down on its own, in parallel; the launcher then sees them exit. stop()
//    signals each child's pid itself. The price: descendants of a child (a wrapper script's own
//    children) are not signalled by stop(); wrappers must `exec` the real program.
//  - Children die with the launcher: each child sets prctl(PR_SET_PDEATHSIG, SIGTERM) after
//    fork and checks getppid() to close the race with a launcher that died meanwhile. Linux
//    sends that signal when the *thread* that forked exits, so call start()/restart() from a
//    thread that lives as long as the children (the main thread).
//  - In the child: every inherited file descriptor above 2 is closed at exec; SIGPIPE (ignored
//    by installStopHandlers()) and the signal mask are reset to the defaults; with log_file,
//    stdout and stderr go to that file (opened O_APPEND, created 0644; its directory must
//    exist); extra env entries are added to (or override) the launcher's environment.
//  - Only this object's children are reaped (waitpid on their pids, never waitpid(-1)), so it
//    coexists with other child processes of the program. A pid is only signalled while it has
//    not been reaped, so a recycled pid is never hit.
//  - Not thread-safe: use one Supervisor from one thread.
#pragma once

#include <sys/types.h>

#include <chrono>
#include <memory>
#include <stdexcept>
#include <string>
#include <utility>
#include <vector>

namespace godhand {

struct ChildSpec {
  std::string name;                ///< unique key ("scene", "solver/left", ...)
  std::vector<std::string> argv;   ///< argv[0] = executable path (or a name looked up in PATH)
  std::vector<std::pair<std::string, std::string>> env;  ///< extra environment variables
  std::string log_file;            ///< "" = inherit stdout/stderr; else both appended to this file
};

struct ChildStatus {
  std::string name;
  pid_t pid = -1;          ///< of the current (or last) run
  bool running = false;    ///< started and not reaped yet
  bool exited = false;     ///< ended by exit(): exit_code is valid
  int exit_code = -1;      ///< when exited
  int term_signal = 0;     ///< when ended by a signal: its number (e.g. SIGTERM from stop())
  int restarts = 0;        ///< how many times restart() (or start() again) ran it after the first start
  std::chrono::steady_clock::time_point started;  ///< of the current run
  std::chrono::steady_clock::time_point ended;    ///< when poll() saw it end (if !running)
};
// A child that is neither running, exited nor signalled vanished without a status (only when
// the program set SIGCHLD to SIG_IGN, which reaps children automatically; don't).

class Supervisor {
 public:
  Supervisor() = default;
  Supervisor(const Supervisor&) = delete;
  Supervisor& operator=(const Supervisor&) = delete;
  /// stop(2 s) if anything is still running.
  ~Supervisor();

  /// Starts a child. Throws std::runtime_error with one line ("NAME: cannot run PATH: reason",
  /// "NAME: already running (pid N)", "NAME: cannot open log file F: reason", ...). Starting a
  /// name that ran before and has ended runs the new spec in its place (counted as a restart).
  void start(const ChildSpec& spec);

  /// Non-blocking: reaps every child that ended and updates its status. Returns the statuses of
  /// the children that ended during this call.
  std::vector<ChildStatus> poll();

  std::vector<ChildStatus> status() const;            ///< in start order
  const ChildStatus* find(const std::string& name) const;  ///< nullptr if unknown; valid as long as the Supervisor

  /// Sends `sig` to a running child; false if unknown, not running, or kill() failed.
  bool signal(const std::string& name, int sig);

  /// Every thread's backtrace of a running child, for a report of where it hung: gdb attached for
  /// a moment (`gdb -p PID -batch -nx -ex "thread apply all bt 30"`), then detached, the child
  /// going on as before. gdb's output (at most 256 KB; gdb is killed after `timeout`), or one line
  /// saying why there is none: unknown or not running, no gdb on PATH, gdb could not run.
  std::string backtraces(const std::string& name, std::chrono::seconds timeout) const;

  /// Runs the same spec again after the child ended (throws std::runtime_error if unknown, still
  /// running, or it cannot run).
  void restart(const std::string& name);

  /// Polls until the child has ended (true) or the timeout passed (false). Throws
  /// std::runtime_error for an unknown name.
  bool waitExit(const std::string& name, std::chrono::milliseconds timeout);
  /// Same for every child.
  bool waitAllExit(std::chrono::milliseconds timeout);

  /// SIGTERM (+ SIGCONT, in case one is stopped) to every running child, waits up to `grace`,
  /// then SIGKILLs the rest and reaps them. Afterwards nothing is running.
  void stop(std::chrono::milliseconds grace);

 private:
  struct Child {
    ChildSpec spec;
    ChildStatus st;
  };
  Child* get(const std::string& name);
  void launch(Child& c, const ChildSpec& spec);  // throws; c unchanged on failure
  bool reap(Child& c, bool block);               // true if it ended now

  std::vector<std::unique_ptr<Child>> children_;
};

}  // namespace godhand
