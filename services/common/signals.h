// Stop signals shared by every godhand program: SIGINT and SIGTERM ask the program to stop (a
// flag the run loop polls, so the program can log its counters and leave cleanly), SIGPIPE is
// ignored (a closed socket or pipe shows up as an EPIPE error instead of killing the process).
//
// The handlers only store into lock-free atomics (async-signal-safe). They are installed with
// SA_RESTART, so blocking system calls in other threads (Fast DDS's) are not interrupted by
// EINTR; loops must therefore poll stopRequested() at a bounded period (sleep in short slices)
// rather than block indefinitely. Every SIGINT/SIGTERM is handled the same way: a program that
// hangs on shutdown needs SIGKILL (godhand-launch's stop() does that after its grace period).
// Children started with exec() get default handlers again; Supervisor also resets SIGPIPE.
#pragma once

#include <chrono>

namespace godhand {

/// Installs the SIGINT / SIGTERM handlers and ignores SIGPIPE. Idempotent.
void installStopHandlers();

/// True once SIGINT or SIGTERM arrived (after installStopHandlers) or requestStop() was called.
bool stopRequested();

/// The first stop signal received (SIGINT or SIGTERM), 0 if none (requestStop() sets none).
int stopSignal();

/// Asks for a stop from code (same effect as a signal, stopSignal() unchanged).
void requestStop();

/// Sleeps up to `timeout` in short slices (<= 10 ms), returning early with true as soon as a
/// stop is requested; false when the time ran out without one. For run loops:
///   while (!waitForStop(std::chrono::milliseconds(100))) { ...periodic work... }
bool waitForStop(std::chrono::milliseconds timeout);

/// What a kill must not lose: makes stdout line-buffered (stderr is unbuffered already), so that a
/// line a program writes to its log (godhand-launch sends a service's stdout and stderr to one
/// file) is in the file once the line ends, not in a buffer that a SIGKILL (a fault drill, the
/// watchdog) throws away. Our own log lines go to stderr; stdout carries what libraries print
/// there (std::cout, printf): block-buffered in a file, a killed process lost them. Call it
/// before anything is written to stdout (every service: first thing in svc::Service).
void lineBufferedStdout();

}  // namespace godhand
