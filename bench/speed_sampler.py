"""A CPU sampler for ``bench/speed.py``: where each process of a measured run spends its CPU.

``bench/speed.py`` copies this file as ``sitecustomize.py`` into a folder it puts on
``PYTHONPATH``, so every Python process of a measured command (``companion simulate``, the
fleet's ``sitl-model`` and companions, a campaign's Dask workers) loads it at start. With
``SPEED_SAMPLE_DIR`` set it arms ``ITIMER_PROF`` (a signal per ``SPEED_SAMPLE_MS`` of the
process's CPU time, user and system) and files each sample under one category by the Python
stack at that moment:

* ``startup``: importing (a frame of ``importlib`` anywhere on the stack);
* ``transport``: MAVLink packing and parsing (pymavlink, the simulator's codec, the group's
  codec and its signing), the in-memory wires and engine loop, the UDP server's and the
  companion's socket loops;
* ``simulator``: ``sitl_model`` (physics, autopilots, telemetry built as messages, world);
* ``companion``: the rest of ``companion`` (Runner, Agent, link estimate, guidance...);
* ``other``: everything else (the report, the campaign's Dask and Parquet, the fleet's
  process management, idle threads).

The innermost frame that names a category decides (a pymavlink call made by the companion is
transport; a numpy call made by the simulator is simulator). A process with several threads
(a Dask worker runs its task in a thread) is filed by the first thread whose stack names a
category other than ``other``. Counts go to ``SPEED_SAMPLE_DIR/PID.json`` every 200 samples
and at exit. The overhead is one stack walk per sample (tens of microseconds every 4 ms).

With ``SPEED_SAMPLE_FUNCS`` set it also counts samples per function of ours (``self``: the
innermost one, the library calls it makes included; ``inclusive``: every one on the stack),
a profile of each process at a fraction of cProfile's cost (``bench/speed.py --profile``).

Nothing of the project is imported: the file works beside any commit of the repository.
"""

from __future__ import annotations

import atexit
import contextlib
import json
import os
import signal
import sys

CATEGORIES = ("startup", "transport", "simulator", "companion", "other")

# (category, path fragments): the first rule whose fragment is in a frame's file name decides
_RULES: tuple[tuple[str, tuple[str, ...]], ...] = (
    (
        "transport",
        (
            "/pymavlink/",
            "patrol-dialect",
            "/fastcrc/",
            "/sitl_model/codec.py",
            "/sitl_model/server.py",
            "/companion/sim/inmemory/wires.py",
            "/companion/sim/inmemory/engine.py",
            "/companion/group/codec.py",
            "/companion/group/transport.py",
            "/companion/contracts/signing.py",
            "/companion/link/connection.py",
            "/companion/process/loop.py",
        ),
    ),
    (
        "other",
        (
            "/companion/report/",
            "/companion/campaign/",
            "/companion/commands/",
            "/companion/sim/fleet.py",
            "/companion/dashboard/",
        ),
    ),
    ("simulator", ("/sitl_model/",)),
    ("companion", ("/companion/",)),
)

_cache: dict[object, str | None] = {}
_counts: dict[str, int] = dict.fromkeys(CATEGORIES, 0)
_state = {"n": 0}


def _code_category(code) -> str | None:
    cat = _cache.get(code, "")
    if cat != "":
        return cat
    name = code.co_filename
    cat = None
    if name.startswith("<frozen importlib"):
        cat = "startup"
    else:
        for c, frags in _RULES:
            if any(f in name for f in frags):
                cat = c
                break
    _cache[code] = cat
    return cat


def _classify(frame) -> str:
    first = None
    f = frame
    while f is not None:
        cat = _code_category(f.f_code)
        if cat == "startup":
            return "startup"
        if first is None and cat is not None:
            first = cat
        f = f.f_back
    return first or "other"


def _functions(frame) -> None:
    """``SPEED_SAMPLE_FUNCS``: count the sample for the innermost function of ours (self,
    library calls included) and for every function of ours on the stack (inclusive)."""
    seen = set()
    own = None
    f = frame
    while f is not None:
        code = f.f_code
        if _code_category(code) is not None:
            key = _names.get(code)
            if key is None:
                parts = code.co_filename.rsplit("/", 2)
                key = _names[code] = f"{'/'.join(parts[-2:])}:{code.co_name}"
            if own is None:
                own = key
            seen.add(key)
        f = f.f_back
    if own is not None:
        _self[own] = _self.get(own, 0) + 1
    for key in seen:
        _inclusive[key] = _inclusive.get(key, 0) + 1


def _on_sample(_signum, frame) -> None:
    with contextlib.suppress(Exception):  # a sampler must never break the run it measures
        _sample(frame)


def _sample(frame) -> None:
    cat = _classify(frame)
    picked = frame
    if cat == "other":
        for f in sys._current_frames().values():
            if f is frame:
                continue
            c = _classify(f)
            if c != "other":
                cat, picked = c, f
                break
    if _FUNCS:
        _functions(picked)
    _counts[cat] += 1
    _state["n"] += 1
    if _state["n"] % 200 == 0:
        _write()


def _write() -> None:
    out = os.environ.get("SPEED_SAMPLE_DIR")
    if not out:
        return
    path = os.path.join(out, f"{os.getpid()}.json")
    rec = {
        "pid": os.getpid(),
        "argv": sys.argv,
        "interval_s": _INTERVAL_S,
        "counts": _counts,
    }
    if _FUNCS:
        rec["self"] = _self
        rec["inclusive"] = _inclusive
    try:
        with open(path + ".tmp", "w") as f:
            json.dump(rec, f)
        os.replace(path + ".tmp", path)
    except OSError:
        pass


def _at_exit() -> None:
    signal.setitimer(signal.ITIMER_PROF, 0.0, 0.0)  # the default action of SIGPROF ends
    signal.signal(signal.SIGPROF, signal.SIG_IGN)  # the process: none during finalisation
    _write()


def _arm() -> None:
    signal.signal(signal.SIGPROF, _on_sample)
    signal.setitimer(signal.ITIMER_PROF, _INTERVAL_S, _INTERVAL_S)


def _forked() -> None:
    for k in _counts:
        _counts[k] = 0
    _state["n"] = 0
    _arm()  # an interval timer is not inherited across fork


_INTERVAL_S = float(os.environ.get("SPEED_SAMPLE_MS", "4")) * 1e-3
_FUNCS = bool(os.environ.get("SPEED_SAMPLE_FUNCS"))
_self: dict[str, int] = {}
_names: dict[object, str] = {}
_inclusive: dict[str, int] = {}
if os.environ.get("SPEED_SAMPLE_DIR"):
    try:
        _arm()
        atexit.register(_at_exit)
        os.register_at_fork(after_in_child=_forked)
    except (ValueError, OSError):  # not the main thread, or no itimer: no samples
        pass
