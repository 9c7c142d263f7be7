"""``companion.process.with_parent``: a command that ends with the process that started it.

Real processes: an intermediate parent starts two ``sleep`` commands, one through the
launcher and one directly, and is then SIGKILLed. The wrapped one must end (SIGTERM from the
kernel); the direct one shows what happened before (it outlives its parent) and is ended
here by pid."""

from __future__ import annotations

import os
import signal
import subprocess
import sys
import textwrap
import time
from pathlib import Path

import pytest

REPO = Path(__file__).resolve().parents[1]
pytestmark = [
    pytest.mark.integration,
    pytest.mark.skipif(
        not sys.platform.startswith("linux"), reason="the parent-death signal is Linux's"
    ),
]


def running(pid: int) -> bool:
    """Whether ``pid`` exists and is not a zombie (an orphan's zombie may wait for a reaper)."""
    try:
        state = Path(f"/proc/{pid}/stat").read_text().rsplit(")", 1)[1].split()[0]
    except (FileNotFoundError, ProcessLookupError, IndexError):
        return False
    return state != "Z"


def wait_until(predicate, timeout_s: float) -> bool:
    deadline = time.monotonic() + timeout_s
    while time.monotonic() < deadline:
        if predicate():
            return True
        time.sleep(0.05)
    return predicate()


def test_the_wrapped_command_ends_when_its_parent_is_killed_and_a_direct_one_does_not(tmp_path):
    pids = tmp_path / "pids"
    script = textwrap.dedent(
        f"""
        import os, subprocess, time
        from companion.process import with_parent
        wrapped = subprocess.Popen(with_parent.command(os.getpid(), ["sleep", "300"]))
        direct = subprocess.Popen(["sleep", "300"])
        open({str(pids)!r} + ".tmp", "w").write(f"{{wrapped.pid}} {{direct.pid}}")
        os.rename({str(pids)!r} + ".tmp", {str(pids)!r})
        time.sleep(300)
        """
    )
    parent = subprocess.Popen([sys.executable, "-c", script], cwd=REPO)
    wrapped = direct = None
    try:
        assert wait_until(pids.is_file, 30), "the parent did not start its children"
        wrapped, direct = (int(p) for p in pids.read_text().split())
        assert running(wrapped) and running(direct)

        def execd() -> bool:  # the launcher has exec'd sleep (a busy machine takes its time)
            return Path(f"/proc/{wrapped}/cmdline").read_bytes().split(b"\0")[0] == b"sleep"

        assert wait_until(execd, 30), "the launcher did not exec the command"
        parent.kill()
        parent.wait()
        assert wait_until(lambda: not running(wrapped), 10), "the wrapped command outlived it"
        assert running(direct)  # without the launcher: an orphan
    finally:
        if parent.poll() is None:
            parent.kill()
            parent.wait()
        for pid in (wrapped, direct):
            if pid is not None and running(pid):
                os.kill(pid, signal.SIGKILL)


def test_a_parent_already_gone_starts_nothing_and_bad_arguments_are_refused(tmp_path):
    marker = tmp_path / "ran"
    # PPID 1 is not this launcher's parent: as if its parent had ended before the request
    gone = subprocess.run(
        [sys.executable, "-m", "companion.process.with_parent", "1", "touch", str(marker)],
        cwd=REPO,
        capture_output=True,
        text=True,
        timeout=60,
    )
    assert gone.returncode == 1 and not marker.exists()
    bad = subprocess.run(
        [sys.executable, "-m", "companion.process.with_parent", "me", "true"],
        cwd=REPO,
        capture_output=True,
        text=True,
        timeout=60,
    )
    assert bad.returncode == 2 and "usage" in bad.stderr
    ok = subprocess.run(
        [sys.executable, "-m", "companion.process.with_parent", str(os.getpid()), "touch",
         str(marker)],
        cwd=REPO,
        timeout=60,
    )  # fmt: skip
    assert ok.returncode == 0 and marker.exists()
