"""What a multi-process test leaves behind, for its `finally`: its DDS domain's processes (killed
after they were reported, a stopped one continued first) and the Fast DDS shared-memory entries
that appeared during the test and that nobody holds any more.

An entry is left behind when no process holds the lock of its `_el` file (what `fastdds shm clean`
removes, and what godhand-launch counts as `shm_segments_left`): the segments of other tests
running in parallel are held by their live processes and are not counted. The domain's port
segments (`fastrtps_port*`), shared by every participant of the host, are not checked."""
import fcntl
import os
import signal
import subprocess
import time


def shm_entries():
    return {n for n in os.listdir("/dev/shm") if "fastrtps" in n}


def unlocked(name):
    """True when nobody holds the lock of /dev/shm/NAME_el (the entry's owner is gone)."""
    try:
        fd = os.open(os.path.join("/dev/shm", name + "_el"), os.O_RDWR)
    except OSError:
        return False
    try:
        fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
    except OSError:
        return False
    else:
        fcntl.flock(fd, fcntl.LOCK_UN)
        return True
    finally:
        os.close(fd)


def orphaned_since(before, wait_s=5.0):
    """Entries new since `before` that nobody holds, after waiting up to wait_s for them to go
    (a launcher removes its killed services' entries as it stops)."""
    deadline = time.time() + wait_s
    while True:
        left = sorted(n for n in shm_entries() - before
                      if not n.endswith("_el") and "fastrtps_port" not in n and unlocked(n))
        if not left or time.time() >= deadline:
            return left
        time.sleep(0.2)


def processes_of_domain(domain, exclude):
    out = subprocess.run(["pgrep", "-af", "godhand-"], capture_output=True, text=True).stdout
    return [l for l in out.splitlines() if f"--domain {domain} " in l + " " and exclude not in l]


def kill_domain(domain, exclude):
    """Continues (a test may have stopped one) and kills the domain's remaining processes."""
    for l in processes_of_domain(domain, exclude):
        pid = int(l.split()[0])
        for sig in (signal.SIGCONT, signal.SIGKILL):
            try:
                os.kill(pid, sig)
            except ProcessLookupError:
                pass
