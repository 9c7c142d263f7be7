"""``python -m companion.process.with_parent PPID COMMAND...`` (or this file as a script):
run COMMAND so that it is sent SIGTERM when the process PPID ends, however it ends (SIGKILL
included).

``companion fleet`` starts every process of a run (the simulator, the companions, the
dashboard, the firmware) in its own session, so that a Ctrl-C in the terminal reaches only
the fleet, which then stops them in order. The price of a session of one's own is that
nothing ends the children if the fleet itself is killed: they were found running, orphaned,
50 minutes after a starved fleet was killed by its test. This launcher asks the kernel for
a parent-death signal (Linux ``prctl(PR_SET_PDEATHSIG, SIGTERM)``, which outlives ``exec``),
checks that PPID is still its parent (it may have ended before the request), then replaces
itself with COMMAND: the pid the fleet holds is COMMAND's, and every process here ends on
SIGTERM in order (the companions and the simulator write their logs first).

Elsewhere than Linux there is no such signal: COMMAND runs as if started directly.
The signal follows the *thread* that started the launcher, so start it from a thread that
lives as long as the run (the fleet starts its processes from its main thread).

Kept to the standard library so that it starts in a few tens of milliseconds.
"""

from __future__ import annotations

import ctypes
import os
import signal
import sys
import threading

PR_SET_PDEATHSIG = 1  # <linux/prctl.h>


def command(ppid: int, argv: list[str]) -> list[str]:
    """``argv`` wrapped so that it receives SIGTERM when process ``ppid`` ends. The launcher
    runs as a script in isolated mode (``-I``): it needs only the standard library, so it
    starts whatever the working directory and however the package is found (an ArduPlane
    instance runs in its own folder); the command keeps the environment as given."""
    return [sys.executable, "-I", os.path.abspath(__file__), str(ppid), *argv]


def guarded(argv: list[str]) -> list[str]:
    """``argv`` to end with this process (:func:`command`) when called from the main thread
    on Linux; otherwise ``argv`` as it is (the signal would follow a thread that may end
    first, and elsewhere there is no such signal)."""
    if sys.platform.startswith("linux") and threading.current_thread() is threading.main_thread():
        return command(os.getpid(), argv)
    return argv


def main(argv: list[str]) -> int:
    """Ask for SIGTERM at the parent's death, then exec the command; 2 on bad arguments,
    1 if the parent has already gone (the command is then not started)."""
    if len(argv) < 2 or not argv[0].isdigit():
        print("usage: python -m companion.process.with_parent PPID COMMAND...", file=sys.stderr)
        return 2
    ppid, cmd = int(argv[0]), argv[1:]
    if sys.platform.startswith("linux"):
        libc = ctypes.CDLL(None, use_errno=True)
        if libc.prctl(PR_SET_PDEATHSIG, int(signal.SIGTERM), 0, 0, 0) != 0:
            err = ctypes.get_errno()
            print(f"with_parent: prctl failed: {os.strerror(err)}", file=sys.stderr)
            return 1
        if os.getppid() != ppid:  # the parent ended before the request: no signal will come
            return 1
    try:
        os.execvp(cmd[0], cmd)
    except OSError as exc:
        print(f"with_parent: cannot run {cmd[0]}: {exc.strerror}", file=sys.stderr)
        return 127
    return 0  # not reached: execvp replaces this process


if __name__ == "__main__":
    raise SystemExit(main(sys.argv[1:]))
