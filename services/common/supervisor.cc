#include "common/supervisor.h"

#include <fcntl.h>
#include <signal.h>
#include <sys/prctl.h>
#include <sys/stat.h>
#include <sys/wait.h>
#include <unistd.h>

#include <algorithm>
#include <cerrno>
#include <cstdlib>
#include <cstring>
#include <thread>

#ifndef CLOSE_RANGE_CLOEXEC
#define CLOSE_RANGE_CLOEXEC (1U << 2)
#endif

extern char** environ;

namespace godhand {

namespace {

using Clock = std::chrono::steady_clock;

/// What the child reports through the exec-status pipe when it cannot exec.
struct ChildFailure {
  int stage;  // kStageRedirect or kStageExec
  int err;    // errno
};
constexpr int kStageRedirect = 1;
constexpr int kStageExec = 2;

std::string errnoText(int err) { return std::strerror(err); }

/// Moves `fd` above 2 (so dup2 onto 1/2 and the child's fd cleanup never clobber it), keeping
/// FD_CLOEXEC. Returns the (possibly new) fd, or -1 with errno set.
int above2(int fd) {
  if (fd < 0 || fd > 2) return fd;
  const int moved = ::fcntl(fd, F_DUPFD_CLOEXEC, 3);
  const int err = errno;
  ::close(fd);
  errno = err;
  return moved;
}

/// 0 if `path` is an executable regular file, else an errno value.
int checkExecutable(const std::string& path) {
  struct stat st;
  if (::stat(path.c_str(), &st) != 0) return errno;
  if (S_ISDIR(st.st_mode)) return EISDIR;
  if (!S_ISREG(st.st_mode)) return EACCES;
  if (::access(path.c_str(), X_OK) != 0) return errno;
  return 0;
}

/// The path to exec for argv[0] (a '/' makes it a path, else it is looked up in PATH, like
/// execvp); throws "NAME: cannot run EXE: reason".
std::string resolveExecutable(const ChildSpec& spec) {
  const std::string& exe = spec.argv[0];
  auto fail = [&](const std::string& reason) -> std::runtime_error {
    return std::runtime_error(spec.name + ": cannot run " + exe + ": " + reason);
  };
  if (exe.empty()) throw fail("empty executable path");
  if (exe.find('/') != std::string::npos) {
    const int err = checkExecutable(exe);
    if (err != 0) throw fail(errnoText(err));
    return exe;
  }
  std::string path;
  bool have_path = false;
  for (const auto& kv : spec.env) {
    if (kv.first == "PATH") {
      path = kv.second;
      have_path = true;
    }
  }
  if (!have_path) {
    const char* p = std::getenv("PATH");
    path = p ? p : "/usr/local/bin:/usr/bin:/bin";
  }
  int first_err = ENOENT;
  size_t begin = 0;
  while (begin <= path.size()) {
    size_t end = path.find(':', begin);
    if (end == std::string::npos) end = path.size();
    const std::string dir = path.substr(begin, end - begin);
    const std::string candidate = (dir.empty() ? std::string(".") : dir) + "/" + exe;
    const int err = checkExecutable(candidate);
    if (err == 0) return candidate;
    if (err != ENOENT && err != ENOTDIR && first_err == ENOENT) first_err = err;
    begin = end + 1;
  }
  throw fail(first_err == ENOENT ? std::string("not found in PATH") : errnoText(first_err));
}

/// The launcher's environment with `extra` added (replacing variables of the same name).
std::vector<std::string> mergedEnvironment(const std::vector<std::pair<std::string, std::string>>& extra) {
  std::vector<std::string> env;
  for (char** e = environ; e && *e; ++e) {
    const std::string entry = *e;
    const std::string key = entry.substr(0, entry.find('='));
    bool overridden = false;
    for (const auto& kv : extra)
      if (kv.first == key) overridden = true;
    if (!overridden) env.push_back(entry);
  }
  for (const auto& kv : extra) {
    // A later duplicate of the same key wins.
    const std::string prefix = kv.first + "=";
    env.erase(std::remove_if(env.begin(), env.end(), [&](const std::string& s) { return s.compare(0, prefix.size(), prefix) == 0; }),
              env.end());
    env.push_back(prefix + kv.second);
  }
  return env;
}

std::vector<char*> cStrings(std::vector<std::string>& strings) {
  std::vector<char*> out;
  out.reserve(strings.size() + 1);
  for (std::string& s : strings) out.push_back(s.data());
  out.push_back(nullptr);
  return out;
}

// ---- in the child, between fork and exec: async-signal-safe calls only ----

[[noreturn]] void childFail(int fd, int stage, int err) {
  const ChildFailure f{stage, err};
  ssize_t w;
  do {
    w = ::write(fd, &f, sizeof f);
  } while (w < 0 && errno == EINTR);
  ::_exit(127);
}

[[noreturn]] void runChild(pid_t parent, int status_fd, int log_fd, long max_fd, const char* path, char* const* argv,
                           char* const* envp) {
  // Signals: handlers inherited from the launcher become the default actions (exec would do
  // that anyway; doing it now means a stop signal arriving before exec still ends the child),
  // SIGPIPE (ignored by installStopHandlers) back to default, nothing blocked.
  for (int sig = 1; sig < NSIG; ++sig) {
    struct sigaction old;
    if (::sigaction(sig, nullptr, &old) != 0) continue;
    const bool handled = (old.sa_flags & SA_SIGINFO) != 0 || (old.sa_handler != SIG_DFL && old.sa_handler != SIG_IGN);
    if (handled || sig == SIGPIPE) {
      struct sigaction dfl;
      std::memset(&dfl, 0, sizeof dfl);
      dfl.sa_handler = SIG_DFL;
      sigemptyset(&dfl.sa_mask);
      ::sigaction(sig, &dfl, nullptr);
    }
  }
  sigset_t none;
  sigemptyset(&none);
  ::sigprocmask(SIG_SETMASK, &none, nullptr);

  // Die with the launcher; if it is already gone, we were reparented before prctl took effect.
  ::prctl(PR_SET_PDEATHSIG, SIGTERM);
  if (::getppid() != parent) ::_exit(127);

  if (log_fd >= 0) {
    if (::dup2(log_fd, STDOUT_FILENO) < 0 || ::dup2(log_fd, STDERR_FILENO) < 0) childFail(status_fd, kStageRedirect, errno);
  }
  // Every inherited descriptor above 2 closes at exec (the status pipe too, which tells the
  // parent that exec succeeded). Fallback for kernels before 5.11: close them now, except the pipe.
  if (::close_range(3, ~0U, CLOSE_RANGE_CLOEXEC) != 0) {
    for (long fd = 3; fd < max_fd; ++fd)
      if (fd != status_fd) ::close(static_cast<int>(fd));
  }
  ::execve(path, argv, envp);
  childFail(status_fd, kStageExec, errno);
}

}  // namespace

Supervisor::~Supervisor() {
  try {
    bool any = false;
    for (const auto& c : children_) any = any || c->st.running;
    if (any) stop(std::chrono::seconds(2));
  } catch (...) {
  }
}

Supervisor::Child* Supervisor::get(const std::string& name) {
  for (auto& c : children_)
    if (c->st.name == name) return c.get();
  return nullptr;
}

const ChildStatus* Supervisor::find(const std::string& name) const {
  for (const auto& c : children_)
    if (c->st.name == name) return &c->st;
  return nullptr;
}

std::vector<ChildStatus> Supervisor::status() const {
  std::vector<ChildStatus> out;
  for (const auto& c : children_) out.push_back(c->st);
  return out;
}

void Supervisor::launch(Child& c, const ChildSpec& spec) {
  if (spec.name.empty()) throw std::runtime_error("supervisor: a child needs a name");
  if (spec.argv.empty()) throw std::runtime_error(spec.name + ": cannot run: empty command line");
  const std::string path = resolveExecutable(spec);

  // Everything the child needs is prepared before fork (it may only make async-signal-safe calls).
  std::vector<std::string> args = spec.argv;
  std::vector<std::string> env = mergedEnvironment(spec.env);
  std::vector<char*> c_argv = cStrings(args);
  std::vector<char*> c_env = cStrings(env);

  int log_fd = -1;
  if (!spec.log_file.empty()) {
    log_fd = above2(::open(spec.log_file.c_str(), O_WRONLY | O_CREAT | O_APPEND | O_CLOEXEC, 0644));
    if (log_fd < 0) throw std::runtime_error(spec.name + ": cannot open log file " + spec.log_file + ": " + errnoText(errno));
  }
  int pipe_fds[2];
  if (::pipe2(pipe_fds, O_CLOEXEC) != 0) {
    const int err = errno;
    if (log_fd >= 0) ::close(log_fd);
    throw std::runtime_error(spec.name + ": cannot start: pipe: " + errnoText(err));
  }
  pipe_fds[0] = above2(pipe_fds[0]);
  pipe_fds[1] = above2(pipe_fds[1]);
  auto closeAll = [&] {
    if (log_fd >= 0) ::close(log_fd);
    if (pipe_fds[0] >= 0) ::close(pipe_fds[0]);
    if (pipe_fds[1] >= 0) ::close(pipe_fds[1]);
  };
  if (pipe_fds[0] < 0 || pipe_fds[1] < 0) {
    const int err = errno;
    closeAll();
    throw std::runtime_error(spec.name + ": cannot start: pipe: " + errnoText(err));
  }
  long max_fd = ::sysconf(_SC_OPEN_MAX);
  if (max_fd <= 0 || max_fd > (1L << 20)) max_fd = 1L << 16;
  const pid_t parent = ::getpid();

  const pid_t pid = ::fork();
  if (pid < 0) {
    const int err = errno;
    closeAll();
    throw std::runtime_error(spec.name + ": cannot start: fork: " + errnoText(err));
  }
  if (pid == 0) runChild(parent, pipe_fds[1], log_fd, max_fd, path.c_str(), c_argv.data(), c_env.data());

  const Clock::time_point started = Clock::now();
  ::close(pipe_fds[1]);
  pipe_fds[1] = -1;
  if (log_fd >= 0) ::close(log_fd);
  log_fd = -1;
  ChildFailure failure{0, 0};
  size_t got = 0;
  while (got < sizeof failure) {
    const ssize_t r = ::read(pipe_fds[0], reinterpret_cast<char*>(&failure) + got, sizeof failure - got);
    if (r < 0 && errno == EINTR) continue;
    if (r <= 0) break;
    got += static_cast<size_t>(r);
  }
  ::close(pipe_fds[0]);
  pipe_fds[0] = -1;
  if (got > 0) {  // the child could not exec: it has _exit()ed or is about to
    int ws;
    while (::waitpid(pid, &ws, 0) < 0 && errno == EINTR) {
    }
    if (got == sizeof failure && failure.stage == kStageRedirect)
      throw std::runtime_error(spec.name + ": cannot redirect output to " + spec.log_file + ": " + errnoText(failure.err));
    throw std::runtime_error(spec.name + ": cannot run " + path + ": " +
                             (got == sizeof failure ? errnoText(failure.err) : std::string("exec failed")));
  }

  c.spec = spec;
  c.st.name = spec.name;
  c.st.pid = pid;
  c.st.running = true;
  c.st.exited = false;
  c.st.exit_code = -1;
  c.st.term_signal = 0;
  c.st.started = started;
  c.st.ended = Clock::time_point();
}

void Supervisor::start(const ChildSpec& spec) {
  if (Child* existing = get(spec.name)) {
    reap(*existing, false);
    if (existing->st.running)
      throw std::runtime_error(spec.name + ": already running (pid " + std::to_string(existing->st.pid) + ")");
    launch(*existing, spec);
    ++existing->st.restarts;
    return;
  }
  auto c = std::make_unique<Child>();
  launch(*c, spec);
  children_.push_back(std::move(c));
}

void Supervisor::restart(const std::string& name) {
  Child* c = get(name);
  if (!c) throw std::runtime_error(name + ": no such child");
  reap(*c, false);
  if (c->st.running) throw std::runtime_error(name + ": still running (pid " + std::to_string(c->st.pid) + ")");
  const ChildSpec spec = c->spec;
  launch(*c, spec);
  ++c->st.restarts;
}

bool Supervisor::reap(Child& c, bool block) {
  if (!c.st.running) return false;
  int ws = 0;
  pid_t r;
  do {
    r = ::waitpid(c.st.pid, &ws, block ? 0 : WNOHANG);
  } while (r < 0 && errno == EINTR);
  if (r == 0) return false;
  c.st.running = false;
  c.st.ended = Clock::now();
  if (r == c.st.pid && WIFEXITED(ws)) {
    c.st.exited = true;
    c.st.exit_code = WEXITSTATUS(ws);
  } else if (r == c.st.pid && WIFSIGNALED(ws)) {
    c.st.term_signal = WTERMSIG(ws);
  }  // else ECHILD: reaped by someone else (SIGCHLD ignored); no status
  return true;
}

std::vector<ChildStatus> Supervisor::poll() {
  std::vector<ChildStatus> ended;
  for (auto& c : children_)
    if (reap(*c, false)) ended.push_back(c->st);
  return ended;
}

bool Supervisor::signal(const std::string& name, int sig) {
  Child* c = get(name);
  if (!c || !c->st.running) return false;
  // Not reaped yet, so the pid is still ours (at worst a zombie): no risk of hitting a recycled pid.
  return ::kill(c->st.pid, sig) == 0;
}

namespace {

/// The first executable `program` on $PATH, or "".
std::string onPath(const char* program) {
  const char* path = std::getenv("PATH");
  std::string dirs = path ? path : "/usr/bin:/bin";
  size_t start = 0;
  while (start <= dirs.size()) {
    const size_t end = std::min(dirs.find(':', start), dirs.size());
    const std::string dir = end > start ? dirs.substr(start, end - start) : ".";
    const std::string candidate = dir + "/" + program;
    if (::access(candidate.c_str(), X_OK) == 0) return candidate;
    start = end + 1;
  }
  return "";
}

}  // namespace

std::string Supervisor::backtraces(const std::string& name, std::chrono::seconds timeout) const {
  const ChildStatus* st = find(name);
  if (!st || !st->running) return "(no backtrace of " + name + ": not running)\n";
  const std::string gdb = onPath("gdb");
  if (gdb.empty()) return "(no backtrace of " + name + ": gdb is not installed)\n";
  int fds[2];
  if (::pipe2(fds, O_CLOEXEC) != 0) return "(no backtrace of " + name + ": pipe: " + std::strerror(errno) + ")\n";
  const std::string pid = std::to_string(st->pid);
  const pid_t child = ::fork();
  if (child < 0) {
    ::close(fds[0]);
    ::close(fds[1]);
    return "(no backtrace of " + name + ": fork: " + std::strerror(errno) + ")\n";
  }
  if (child == 0) {  // gdb's output (both streams) into the pipe; nothing else inherited
    ::dup2(fds[1], STDOUT_FILENO);
    ::dup2(fds[1], STDERR_FILENO);
    const int null = ::open("/dev/null", O_RDONLY);
    if (null >= 0) ::dup2(null, STDIN_FILENO);
    ::close_range(3, ~0U, CLOSE_RANGE_CLOEXEC);  // the launcher's sockets and files stay its own
    const char* argv[] = {gdb.c_str(), "-p", pid.c_str(), "-batch", "-nx", "-ex", "thread apply all bt 30", nullptr};
    ::execv(gdb.c_str(), const_cast<char* const*>(argv));
    ::_exit(127);
  }
  ::close(fds[1]);
  ::fcntl(fds[0], F_SETFL, ::fcntl(fds[0], F_GETFL) | O_NONBLOCK);
  constexpr size_t kMaxOutput = 256 * 1024;
  std::string out;
  const Clock::time_point deadline = Clock::now() + timeout;
  bool timed_out = false;
  for (;;) {
    char buf[4096];
    const ssize_t n = ::read(fds[0], buf, sizeof buf);
    if (n > 0) {
      if (out.size() < kMaxOutput) out.append(buf, static_cast<size_t>(std::min<ssize_t>(n, static_cast<ssize_t>(kMaxOutput - out.size()))));
      continue;
    }
    if (n == 0) break;  // gdb closed its end: done
    if (errno != EAGAIN && errno != EWOULDBLOCK && errno != EINTR) break;
    if (Clock::now() > deadline) {
      timed_out = true;
      break;
    }
    std::this_thread::sleep_for(std::chrono::milliseconds(20));
  }
  ::close(fds[0]);
  if (timed_out) ::kill(child, SIGKILL);  // (gdb detaches from the child when it dies)
  int wstatus = 0;
  while (::waitpid(child, &wstatus, 0) < 0 && errno == EINTR) {
  }
  if (timed_out) out += "(gdb killed after " + std::to_string(timeout.count()) + " s)\n";
  else if (WIFEXITED(wstatus) && WEXITSTATUS(wstatus) == 127 && out.empty()) out = "(no backtrace of " + name + ": " + gdb + " could not run)\n";
  return out;
}

namespace {

/// Polls `done` with growing naps (1 ms .. 20 ms) until it is true or the deadline passed.
template <class Done>
bool pollUntil(Done done, std::chrono::milliseconds timeout) {
  const Clock::time_point deadline = Clock::now() + timeout;
  Clock::duration nap = std::chrono::milliseconds(1);
  for (;;) {
    if (done()) return true;
    const Clock::time_point now = Clock::now();
    if (now >= deadline) return false;
    std::this_thread::sleep_for(std::min(nap, deadline - now));
    nap = std::min<Clock::duration>(nap * 2, std::chrono::milliseconds(20));
  }
}

}  // namespace

bool Supervisor::waitExit(const std::string& name, std::chrono::milliseconds timeout) {
  Child* c = get(name);
  if (!c) throw std::runtime_error(name + ": no such child");
  return pollUntil(
      [&] {
        reap(*c, false);
        return !c->st.running;
      },
      timeout);
}

bool Supervisor::waitAllExit(std::chrono::milliseconds timeout) {
  return pollUntil(
      [&] {
        poll();
        for (const auto& c : children_)
          if (c->st.running) return false;
        return true;
      },
      timeout);
}

void Supervisor::stop(std::chrono::milliseconds grace) {
  poll();
  bool any = false;
  for (auto& c : children_) {
    if (!c->st.running) continue;
    ::kill(c->st.pid, SIGTERM);
    ::kill(c->st.pid, SIGCONT);  // a stopped process acts on SIGTERM only once continued
    any = true;
  }
  if (!any) return;
  waitAllExit(grace);
  for (auto& c : children_) {
    if (!c->st.running) continue;
    ::kill(c->st.pid, SIGKILL);
    reap(*c, true);
  }
}

}  // namespace godhand
