"""One wind for the whole fleet (pure): members' estimates in, an agreed wind record out.

Every member must use the same wind for the time-phase (eq. 14), the period (eq. 15) and the
planner, or their phases mean different things. Each member shares its own wind estimate in
its state; the fleet adopts one wind, identical on every member and switched at an agreed
vehicle time:

* The **proposer** is the member with the lowest system id among the members it hears
  (itself included). Only the proposer creates records. It combines the fresh, valid
  estimates robustly (:func:`robust_wind`: the mean of the estimates within ``INLIER_M_S``
  of their component-wise median, so one wild member cannot drag the fleet, while the
  biases that turn with each aircraft's heading average out across members spread round
  the loop, as a median's would not) and proposes a new record when the combination
  differs from the wind in force by more than ``threshold_m_s`` for ``dwell_s``
  (hysteresis), at most once per ``min_interval_s``, effective ``lead_s`` after it is made
  so every member has heard it. The defaults (0.25 m/s, 5 s, 5 s) follow the wind closely:
  a wrong wind costs more than a switch. Measured on the ellipse (robustness bench, in
  memory): a wind left 0.3 m/s off after a step held the cross-track p95 at about 6 m
  against 0.7 m before it; a drifting wind followed with 0.5 m/s / 5 s / 15 s read 17.6 m
  p95, with 0.25 m/s / 5 s / 5 s 10.8 m; under 1.5 m/s gusts, switching every 30 s or
  never read the same (24-26 m p95). Below 0.25 m/s / 5 s the scatter of the estimates
  themselves switches the wind in still air (0.2 m/s / 2 s: 8 switches in 900 s,
  cross-track p95 3.2 m against 1.7 m).
* **Rate.** Adopting another wind moves every slot of the time-splay along the loop, each
  by its own amount (:func:`companion.guidance.formation.slot_shift_per_wind_s`: about 22 m per
  m/s on the paper's ellipse, 440 m per m/s on WPAFB). With ``max_rate_m_s2`` set (the
  Agent sets the airspeed's authority over that shift), a new record moves from the newest
  one by at most the rate times the time since this proposer's last record (at most
  ``MAX_RATE_CREDIT_S`` of it), so the slots never move faster than the airspeed can
  follow; the first record, from the mission's guess, is taken whole. Measured on WPAFB in
  1.5 m/s gusts: unlimited, the gusts switched the wind every 8-10 s by about 0.5 m/s, each
  switch moving slots by up to 285 m (docs/robustness.md, "WPAFB").
* A **record** is ``(seq, proposer, wind, t_eff_s)``. Every member relays the newest record it
  knows in its state; a member adopts a record that is newer by ``(seq, -proposer)``: a higher
  sequence wins, and of two records with the same sequence (two members that briefly both
  thought they were the proposer) the lower proposer's. A newcomer adopts the fleet's record
  from the first state it hears. The mission's wind is record 0, the first guess.
* The wind in force at vehicle time ``t`` is the newest known record with ``t_eff_s <= t``
  (the previous one until then).

Bad input (a NaN, a negative speed, a speed at or above the airspeed, from the autopilot or a
member) is ignored and counted in :attr:`WindAgreement.counts`; it never steers.

Conventions: wind vectors ``north + i east`` (m/s) in the direction the air moves towards;
times are vehicle seconds, passed in.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

from companion.core.wind import valid_wind
from companion.group.messages import WindRecord

__all__ = ["WindAgreement", "WindRecord", "robust_wind", "valid_wind"]

MAX_RECORDS = 8  # records kept (the one in force and those due later)
MAX_RATE_CREDIT_S = 30.0  # a rate-limited record moves at most 30 s worth of the rate
INLIER_M_S = 1.0  # an estimate this far (m/s) from the members' median is left out of the mean


def robust_wind(estimates: list[complex], inlier_m_s: float = INLIER_M_S) -> complex:
    """The members' wind (m/s): the mean of the estimates within ``inlier_m_s`` (m/s) of
    their component-wise median (the median itself if none is); needs at least one.

    Why the mean of inliers and not the median: an autopilot's estimate carries a bias that
    turns with the aircraft's heading (ArduPlane SITL's WIND read 4.72-5.13 m/s by heading
    in a 5.0 m/s wind). Members spread round the loop see that bias at different headings:
    their mean cancels much of it, their median follows whichever member is in the middle,
    which changes every T/N. Over 250-590 s of a three-ArduPlane run, the median of the three
    WIND messages swung 4.80-4.99 m/s, their mean 4.89-4.91 m/s.
    """
    if not estimates:
        raise ValueError("no wind estimate to combine")
    # a handful of members: Python scalars, numpy's median and mean in their order
    med = complex(_median([w.real for w in estimates]), _median([w.imag for w in estimates]))
    near = [w for w in estimates if abs(w - med) <= inlier_m_s]
    if not near:
        return med
    total = sum(near, 0j)
    return complex(total.real / len(near), total.imag / len(near))


def _median(values: list[float]) -> float:
    """The median of ``values`` (not empty): the middle one, or the mean of the two."""
    s = sorted(values)
    h = len(s) // 2
    return s[h] if len(s) % 2 else (s[h - 1] + s[h]) / 2


@dataclass
class WindAgreement:
    """One member's view of the fleet's wind (see the module docstring).

    Args:
        sysid: this member's system id.
        airspeed_m_s: the fleet's airspeed (m/s), bounds a valid wind.
        initial_m_s: the mission's wind (m/s, towards), record 0.
        threshold_m_s: change (m/s, vector magnitude) that calls for a new record.
        dwell_s: how long the change must persist (s).
        min_interval_s: least time between two records of this proposer (s).
        lead_s: a record takes effect this long after it is made (s).
        stale_s: an estimate older than this (local receipt time) is not used (s).
        max_rate_m_s2: fastest the agreed wind may move (m/s per s of vehicle time): a new
            record moves from the newest one towards the combination by at most this times
            the time since this proposer's last record (0 = no limit; see the module
            docstring, "Rate").
    """

    sysid: int
    airspeed_m_s: float
    initial_m_s: complex
    threshold_m_s: float = 0.25
    dwell_s: float = 5.0
    min_interval_s: float = 5.0
    lead_s: float = 2.0
    stale_s: float = 5.0
    max_rate_m_s2: float = 0.0
    records: list[WindRecord] = field(default_factory=list)
    estimates: dict[int, tuple[complex, float]] = field(default_factory=dict)
    counts: dict[str, int] = field(default_factory=lambda: {"bad_own": 0, "bad_member": 0})
    _since_s: float | None = None
    _last_made_s: float = -math.inf

    def __post_init__(self) -> None:
        """Record 0 is the mission's wind, in force from the start."""
        if not valid_wind(self.initial_m_s, self.airspeed_m_s):
            raise ValueError(f"the mission's wind {self.initial_m_s!r} is not usable")
        if not self.records:
            self.records = [WindRecord(0, 0, complex(self.initial_m_s), -math.inf)]

    # ---- inputs -------------------------------------------------------------------------
    def own_estimate(self, wind_m_s: complex | None, t_s: float) -> bool:
        """This member's estimate (m/s) at ``t_s`` (s); False (and counted) if refused."""
        if wind_m_s is None:
            return False
        if not valid_wind(wind_m_s, self.airspeed_m_s):
            self.counts["bad_own"] += 1
            return False
        self.estimates[self.sysid] = (complex(wind_m_s), float(t_s))
        return True

    def member_estimate(self, sysid: int, wind_m_s: complex | None, rx_t_s: float) -> bool:
        """A member's shared estimate (m/s), received at local time ``rx_t_s`` (s)."""
        if wind_m_s is None:
            return False
        if not valid_wind(wind_m_s, self.airspeed_m_s):
            self.counts["bad_member"] += 1
            return False
        self.estimates[int(sysid)] = (complex(wind_m_s), float(rx_t_s))
        return True

    def member_record(self, record: WindRecord | None) -> bool:
        """A record relayed by a member; True if it was adopted (newer than all known)."""
        if record is None:
            return False
        if not valid_wind(record.wind_m_s, self.airspeed_m_s) or not math.isfinite(record.t_eff_s):
            self.counts["bad_member"] += 1
            return False
        if not record.newer_than(self.latest):
            return False
        self._adopt(record)
        return True

    def forget(self, sysid: int) -> None:
        """A member left the formation: its estimate no longer counts."""
        self.estimates.pop(int(sysid), None)

    # ---- outputs ------------------------------------------------------------------------
    @property
    def latest(self) -> WindRecord:
        """The newest known record (possibly not yet in force)."""
        return self.records[-1]

    def record_at(self, t_s: float) -> WindRecord:
        """The record in force at vehicle time ``t_s`` (s)."""
        for rec in reversed(self.records):
            if rec.t_eff_s <= t_s:
                return rec
        return self.records[0]

    def wind_at(self, t_s: float) -> complex:
        """The agreed wind (m/s, towards) in force at ``t_s`` (s)."""
        return self.record_at(t_s).wind_m_s

    def combined(self, t_s: float) -> complex | None:
        """Robust combination of the fresh estimates at ``t_s`` (m/s), None without any."""
        fresh = [w for w, t in self.estimates.values() if t_s - t <= self.stale_s]
        return robust_wind(fresh) if fresh else None

    def step(self, t_s: float, members: set[int]) -> WindRecord | None:
        """Proposer's duty at ``t_s`` (s), ``members`` the other members heard now.

        Returns the new record if this member made one (it is also adopted).
        """
        if members and min(members) < self.sysid:
            self._since_s = None
            return None  # someone else proposes
        combined = self.combined(t_s)
        if combined is None:
            return None
        if abs(combined - self.latest.wind_m_s) <= self.threshold_m_s:
            self._since_s = None
            return None
        if self._since_s is None:
            self._since_s = t_s
        if t_s - self._since_s < self.dwell_s or t_s - self._last_made_s < self.min_interval_s:
            return None
        latest = self.latest
        wind = combined
        if self.max_rate_m_s2 > 0 and latest.seq > 0:  # the mission's wind is only a guess
            room = self.max_rate_m_s2 * min(t_s - self._last_made_s, MAX_RATE_CREDIT_S)
            change = combined - latest.wind_m_s
            if abs(change) > room:
                wind = latest.wind_m_s + change * (room / abs(change))
        rec = WindRecord(latest.seq + 1, self.sysid, wind, t_s + self.lead_s)
        self._adopt(rec)
        self._last_made_s = t_s
        self._since_s = None
        return rec

    def _adopt(self, rec: WindRecord) -> None:
        # A newer record supersedes every record due at or after its own time; the earlier
        # ones stay (one of them is in force until rec's time), the oldest few dropped.
        kept = [r for r in self.records if r.t_eff_s < rec.t_eff_s]
        self.records = [*kept[-(MAX_RECORDS - 1) :], rec]
