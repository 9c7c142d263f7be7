"""One pytest run for both tiers: the free-running tests start first, at full priority, on
the first two workers; every other test runs beside them on workers that lowered their own
priority (``nice``), so it takes only the CPU the free-running flights leave.

Why: a free-running flight (real firmware paced by the wall clock) must not be starved, and it
leaves most of a core idle (measured 2026-12-05: the 48 ``alone`` tests used 1.08 cores over
their 472 s). Run apart, after the rest, that idle core was lost; beside CPU-bound workers of
the same priority a flight would compete for the CPU on equal terms (two firmware fleets
flown together made a companion's group traffic 2 s of vehicle time late). A
worker that has run a test without the ``alone`` mark is niced (``NICE``) and, since an
unprivileged process cannot raise its priority again, never takes an ``alone`` test after.

``AloneFirstScheduling`` is xdist's ``loadgroup`` with one rule: a scope (group) named
``ALONE_PREFIX...`` goes only to one of the first ``ALONE_WORKERS`` workers, and only before
that worker has taken any other scope; the firmware group first, as the longest."""

from __future__ import annotations

import os

from xdist.scheduler import LoadGroupScheduling

# the group name's prefix of the tests marked ``alone`` (tests/conftest.py sets it)
ALONE_PREFIX = "alone-"
# the group of the real-firmware fleets, flown one after another: the longest chain, so first
FIRMWARE_GROUP = ALONE_PREFIX + "firmware"
# how many workers take the alone tests: two at a time, as before the tiers were one run
ALONE_WORKERS = 2
# the other workers' niceness. At 19 (a CFS weight of 15 against a firmware process's 1024)
# they all but stopped while the flights were busy, and wall-clock bounds made for a worker
# with a core of its own failed (a 2 s wait for a heartbeat, a 60 s stop); at 5 (weight 335)
# the two or three of them weigh together about one worker of full priority, as the one other
# alone module that flew beside the firmware before the tiers were one run
NICE = 5


class AloneFirstScheduling(LoadGroupScheduling):
    """``loadgroup`` scheduling where the ``alone`` groups go first, and only, to the first
    ``ALONE_WORKERS`` workers that have taken nothing else."""

    def __init__(self, config, log=None) -> None:
        super().__init__(config, log)
        self._took_shared: set = set()

    def _may_take_alone(self, node) -> bool:
        worker = node.gateway.id  # "gw0", "gw1", ...
        first = worker in {f"gw{i}" for i in range(ALONE_WORKERS)}
        return first and node not in self._took_shared

    def _assign_work_unit(self, node) -> None:
        """Send ``node`` its next scope: an ``alone`` one if it may take one and one is left
        (the firmware group first), else the next other one; nothing if neither."""
        alone = [s for s in self.workqueue if s.startswith(ALONE_PREFIX)]
        if alone and self._may_take_alone(node):
            scope = FIRMWARE_GROUP if FIRMWARE_GROUP in alone else alone[0]
        else:
            shared = [s for s in self.workqueue if not s.startswith(ALONE_PREFIX)]
            if not shared:
                return  # only alone scopes are left, for the workers that may take them
            scope = shared[0]
            self._took_shared.add(node)
        work_unit = self.workqueue.pop(scope)
        self.assigned_work.setdefault(node, {})[scope] = work_unit
        collection = self.registered_collections[node]
        node.send_runtest_some([collection.index(n) for n, done in work_unit.items() if not done])


def lower_priority_once() -> None:
    """Nice this worker by ``NICE`` (once; later calls do nothing): it has run, or is about to
    run, a test that is not ``alone``, so from now on it yields to the free-running ones."""
    global _niced
    if not _niced:
        os.nice(NICE)
        _niced = True


_niced = False
