"""Supervising the autopilot (pure): is it flying, does it fly what is sent, and how fast.

Nothing here sends or reads a clock: every call takes the vehicle time ``t_s`` (s).

* :func:`default_profile`: the setpoint profile for an autopilot type (HEARTBEAT
  ``autopilot``): ArduPilot -> ``bank`` (type_mask 0xFE, the only attitude setpoint
  ArduPlane flies as sent, with TECS keeping speed and height: docs/arduplane.md), PX4 ->
  ``PX4_DEFAULT_PROFILE`` (docs/px4.md), any other -> ``turn-rate`` (rate-controlled
  autopilots that read ``body_yaw_rate``).
* :func:`not_flying_reason`: whether an aircraft may be taken over (armed, in the air by
  EXTENDED_SYS_STATE where it is streamed, high enough above home, near its cruise airspeed).
* :class:`AirspeedMonitor`: the airspeed (VFR_HUD) more than ``tol_frac`` away from the
  mission's for longer than ``hold_s``.
* :class:`ResponseMonitor`: the achieved turn rate does not follow the command over a window
  (the profile is ignored, e.g. ArduPlane flying its own loiter), or the aircraft is not
  moving at all (on the ground).

Monitors return ``Issue`` transitions (raised / cleared) for the runner to report (event,
STATUSTEXT, status line).
"""

from __future__ import annotations

import math
import statistics
from collections import deque
from dataclasses import dataclass

from companion.link.setpoints import G_M_S2, Profile

MAV_AUTOPILOT_ARDUPILOTMEGA = 3
MAV_AUTOPILOT_PX4 = 12
PX4_DEFAULT_PROFILE: Profile = "attitude"  # measured against "path": docs/px4.md
MAV_LANDED_STATE_IN_AIR = 2
LANDED_STATES = {0: "UNDEFINED", 1: "ON_GROUND", 2: "IN_AIR", 3: "TAKEOFF", 4: "LANDING"}

TAKE_OVER_ALT_FRAC = 0.5  # take over above this fraction of the mission altitude...
TAKE_OVER_ALT_MIN_M = 20.0  # ...and never below this height above home (m)
TAKE_OVER_AIRSPEED_FRAC = 0.7  # ...at no less than this fraction of the mission airspeed


def default_profile(autopilot: int | None) -> Profile:
    """The setpoint profile for an autopilot of HEARTBEAT type ``autopilot`` (MAV_AUTOPILOT).

    ArduPilot (3): ``bank``. ArduPlane ignores ``body_yaw_rate`` entirely (the turn-rate
    profile steers nothing); the bank profile measured best on ArduPlane SITL (20.0 m/s held,
    altitude within 0.5 m, cross-track 6.8 m median, against 12 m for the heading profile).
    PX4 (12): ``PX4_DEFAULT_PROFILE``: PX4 refuses 0xC3 and 0xFE as offboard setpoints.
    Any other autopilot: ``turn-rate``.
    """
    if autopilot == MAV_AUTOPILOT_PX4:
        return PX4_DEFAULT_PROFILE
    return "bank" if autopilot == MAV_AUTOPILOT_ARDUPILOTMEGA else "turn-rate"


def take_over_min_alt_m(mission_alt_m: float) -> float:
    """Least height above home (m) at which an aircraft counts as flown, not climbing out."""
    return min(mission_alt_m, max(TAKE_OVER_ALT_MIN_M, TAKE_OVER_ALT_FRAC * mission_alt_m))


def not_flying_reason(
    armed: bool | None,
    landed_state: int | None,
    rel_alt_m: float | None,
    airspeed_m_s: float | None,
    mission_alt_m: float,
    cruise_m_s: float,
) -> str | None:
    """None if the aircraft is flying and may be taken over; otherwise why not (short text).

    Args:
        armed: HEARTBEAT armed flag (None: not heard yet).
        landed_state: EXTENDED_SYS_STATE ``landed_state`` (None: not streamed).
        rel_alt_m: GLOBAL_POSITION_INT ``relative_alt`` (m above home; None: not heard yet).
        airspeed_m_s: VFR_HUD airspeed (m/s; None: not streamed).
        mission_alt_m: this vehicle's mission altitude above the origin (m).
        cruise_m_s: the mission airspeed (m/s).
    """
    if not armed:
        return "disarmed"
    if landed_state is not None and landed_state != MAV_LANDED_STATE_IN_AIR:
        return f"landed state {LANDED_STATES.get(landed_state, landed_state)}"
    if rel_alt_m is None:
        return "no position yet"
    floor = take_over_min_alt_m(mission_alt_m)
    if rel_alt_m < floor:
        return f"{rel_alt_m:.0f} m above home, below {floor:.0f} m"
    if airspeed_m_s is not None and airspeed_m_s < TAKE_OVER_AIRSPEED_FRAC * cruise_m_s:
        return f"airspeed {airspeed_m_s:.1f} m/s, below {TAKE_OVER_AIRSPEED_FRAC * cruise_m_s:.1f}"
    return None


@dataclass(frozen=True)
class Issue:
    """A supervision finding that changed: ``name`` raised (``active``) or cleared."""

    name: str
    active: bool
    text: str


class AirspeedMonitor:
    """Airspeed far from the mission's: ``|V - V_m| > tol_frac V_m`` for ``hold_s`` (s).

    Args:
        target_m_s: the mission airspeed (m/s).
        tol_frac: tolerated relative deviation.
        hold_s: how long the deviation must last before it is reported (vehicle s).
    """

    NAME = "airspeed_off"

    def __init__(self, target_m_s: float, tol_frac: float = 0.15, hold_s: float = 10.0) -> None:
        """Nothing observed yet."""
        self.target_m_s = float(target_m_s)
        self.tol_frac = tol_frac
        self.hold_s = hold_s
        self.active = False
        self._off_since: float | None = None
        self._ok_since: float | None = None
        self.last_m_s: float | None = None

    def update(self, t_s: float, airspeed_m_s: float) -> Issue | None:
        """One airspeed reading (m/s) at ``t_s`` (s); the transition, if any."""
        if not math.isfinite(airspeed_m_s):
            return None
        self.last_m_s = airspeed_m_s
        off = abs(airspeed_m_s - self.target_m_s) > self.tol_frac * self.target_m_s
        if off:
            self._ok_since = None
            if self._off_since is None:
                self._off_since = t_s
            if not self.active and t_s - self._off_since >= self.hold_s:
                self.active = True
                return Issue(
                    self.NAME,
                    True,
                    f"airspeed {airspeed_m_s:.1f} m/s, mission {self.target_m_s:.1f}",
                )
        else:
            self._off_since = None
            if self._ok_since is None:
                self._ok_since = t_s
            if self.active and t_s - self._ok_since >= self.hold_s:
                self.active = False
                return Issue(self.NAME, False, f"airspeed {airspeed_m_s:.1f} m/s again")
        return None

    def reset(self) -> None:
        """Forget the timing (not commanding: the airspeed is not ours to judge)."""
        self._off_since = self._ok_since = None


SATURATED_FRACTION = 0.9  # a command this close to the turn-rate limit says nothing of the profile
GAIN_TOLERANCE = 0.35  # residual tolerated in proportion to the expected turn rate
TAKE_OVER_GRACE_S = 5.0  # samples of the first seconds of commanding are not judged
# s: first-order roll lag the expected turn rate is passed through; longer than the shaper's
# AUTOPILOT_LAG_S (0.3 s, for the gain estimate) so an alarm errs on the slow aircraft's side
RESPONSE_LAG_S = 0.5
MIN_JUDGED_FRACTION = 0.5  # of a window's samples, to judge it at all


class ResponseMonitor:
    """Does the aircraft turn as commanded? Over the last ``window_s`` of commanding:

    * ``profile_ignored``: the mean ``|achieved - gain x|`` exceeds ``resid_rad_s`` and the
      achieved turn rate does not co-vary with the command (centred regression slope below
      ``min_slope``, or too little variation of the command to tell): the autopilot flies
      something else, e.g. its own loiter;
    * ``not_responding``: the ground speed stayed below ``min_groundspeed_m_s`` (on the
      ground, or no position updates moving).

    ``x`` is the setpoint's nominal turn rate (rad/s) in force over the sample and ``gain``
    the shaper's achieved-turn-rate gain (see :mod:`companion.link.shaping`). A sample whose
    expected turn rate ``gain x`` is beyond ``SATURATED_FRACTION`` of the aircraft's limit
    ``max_turn_rate_rad_s`` is left out: there the autopilot's own roll limit, not the
    profile, sets the turn (on six ArduPlanes acquiring the splay, commands held at the limit
    raised 11-19 false ``profile_ignored`` per run), and a residual up to ``GAIN_TOLERANCE``
    of the expected turn rate is tolerated besides ``resid_rad_s`` (the gain being learnt;
    with the limit alone, six ArduPlanes still raised 10 in a run, at 2.9-6.4 deg/s), and
    the first ``TAKE_OVER_GRACE_S`` after a start or reset are not judged (the aircraft rolls
    out of the turn it was flying: 5.0-6.6 deg/s over the first window at take-over).

    The expected turn rate is ``gain x`` passed through a first-order lag of
    ``RESPONSE_LAG_S`` (the aircraft rolls into a new command; its time step is the interval
    between samples), and a window is judged only when at least ``MIN_JUDGED_FRACTION`` of
    its samples were judged. Acquiring the splay the law swings between the limits: judged
    on the crossings alone against the unlagged command, three ArduPlanes raised six false
    ``profile_ignored`` in 720 s (3.5-10.5 deg/s "off"); with the lag and the rule, 0 and 1
    in two runs of the same (2026-12-02, ``companion fleet tests/data/ellipse_3uav.yaml
    --autopilot arduplane --speedup 5 --duration 720``).
    """

    def __init__(
        self,
        window_s: float = 10.0,
        resid_rad_s: float = 0.05,
        min_slope: float = 0.3,
        min_groundspeed_m_s: float = 3.0,
        max_turn_rate_rad_s: float = math.inf,
    ) -> None:
        """Nothing observed yet."""
        self.max_turn_rate_rad_s = max_turn_rate_rad_s
        self.window_s = window_s
        self.resid_rad_s = resid_rad_s
        self.min_slope = min_slope
        self.min_gs = min_groundspeed_m_s
        self._samples: deque[tuple[float, float, float, float]] = deque()  # t, x, y, r
        self._resid_abs: deque[float] = deque()  # |r| of each sample, in step with _samples
        self._seen: deque[tuple[float, bool]] = deque()  # t, judged: every sample
        self._lagged: float | None = None  # gain x through the roll lag (rad/s)
        self._last_t_s: float | None = None
        self._slow_since: float | None = None
        self._since_s: float | None = None  # first sample after a start or reset
        self.active: dict[str, bool] = {"profile_ignored": False, "not_responding": False}

    def reset(self) -> None:
        """Forget the window (commanding stopped or the link was lost)."""
        self._samples.clear()
        self._resid_abs.clear()
        self._seen.clear()
        self._lagged = self._last_t_s = None
        self._slow_since = None
        self._since_s = None

    def update(
        self,
        t_s: float,
        x_rad_s: float | None,
        achieved_rad_s: float | None,
        gain: float,
        groundspeed_m_s: float,
    ) -> list[Issue]:
        """One sample while commanding at ``t_s`` (s); the transitions, if any."""
        issues: list[Issue] = []
        slow = groundspeed_m_s < self.min_gs
        if slow:
            if self._slow_since is None:
                self._slow_since = t_s
        else:
            self._slow_since = None
        stuck = self._slow_since is not None and t_s - self._slow_since >= self.window_s / 2
        issues += self._set(
            "not_responding",
            stuck,
            f"ground speed {groundspeed_m_s:.1f} m/s: not flying" if stuck else "moving again",
        )
        if self._since_s is None:
            self._since_s = t_s
        settling = t_s - self._since_s < TAKE_OVER_GRACE_S  # rolling out of its own turn
        lagged = self._lag(t_s, None if x_rad_s is None else gain * x_rad_s)
        limit = SATURATED_FRACTION * self.max_turn_rate_rad_s
        saturated = x_rad_s is not None and max(abs(gain * x_rad_s), abs(lagged)) > limit
        judged = x_rad_s is not None and achieved_rad_s is not None and not settling
        judged = judged and not saturated
        self._seen.append((t_s, judged))
        if judged and x_rad_s is not None and achieved_rad_s is not None:  # (judged: both are)
            resid_rad_s = achieved_rad_s - lagged
            self._samples.append((t_s, x_rad_s, achieved_rad_s, resid_rad_s))
            self._resid_abs.append(abs(resid_rad_s))
        while self._samples and self._samples[0][0] < t_s - self.window_s:
            self._samples.popleft()
            self._resid_abs.popleft()
        while self._seen and self._seen[0][0] < t_s - self.window_s:
            self._seen.popleft()
        if not self._samples or self._samples[-1][0] - self._samples[0][0] < 0.9 * self.window_s:
            return issues
        if len(self._samples) < MIN_JUDGED_FRACTION * len(self._seen):
            return issues  # mostly at the limit or rolling: too little to tell
        n = len(self._samples)
        resid = sum(self._resid_abs) / n
        # Within resid_rad_s the profile is not ignored whatever the rest (the allowance only
        # grows it): the regression is worked out only for a larger residual (every step).
        ignored = resid > self.resid_rad_s and self._ignored(resid, n, gain)
        following = resid < 0.6 * self.resid_rad_s
        if ignored:
            issues += self._set(
                "profile_ignored",
                True,
                f"turn not followed: {math.degrees(resid):.1f} deg/s off for {self.window_s:.0f} s",
            )
        elif following:
            issues += self._set("profile_ignored", False, "turn followed again")
        return issues

    def _ignored(self, resid: float, n: int, gain: float) -> bool:
        """Whether a window of ``n`` samples with mean residual ``resid`` (rad/s) shows the
        profile ignored, at the shaper's ``gain``: the residual beyond what a gain still
        being learnt explains, and the achieved turn rate not co-varying with the command."""
        xs = [s[1] for s in self._samples]
        ys = [s[2] for s in self._samples]
        mx, my = sum(xs) / n, sum(ys) / n
        sxx = sum((x - mx) ** 2 for x in xs)
        sxy = sum((x - mx) * (y - my) for x, y in zip(xs, ys, strict=True))
        varied = sxx / n >= (0.2 * self.resid_rad_s) ** 2
        slope = sxy / sxx if sxx > 0 else 0.0
        # a gain still being learnt (ArduPlane starts at 1.0 and settles near 0.7) leaves a
        # residual in proportion to the command: tolerated up to GAIN_TOLERANCE of it
        expected = sum(abs(gain * x) for x in xs) / n
        allowed = self.resid_rad_s + GAIN_TOLERANCE * expected
        return resid > allowed and (not varied or slope < self.min_slope)

    def _lag(self, t_s: float, expected_rad_s: float | None) -> float:
        """``expected_rad_s`` (rad/s) through a first-order lag of ``RESPONSE_LAG_S``,
        stepped to ``t_s`` (s); restarted from the command after a gap or without one."""
        last, self._last_t_s = self._last_t_s, t_s
        if expected_rad_s is None:
            self._lagged = None
            return 0.0
        if self._lagged is None or last is None or not 0.0 < t_s - last <= 1.0:
            self._lagged = expected_rad_s
        else:
            decay = math.exp(-(t_s - last) / RESPONSE_LAG_S)
            self._lagged = expected_rad_s + (self._lagged - expected_rad_s) * decay
        return self._lagged

    def _set(self, name: str, active: bool, text: str) -> list[Issue]:
        if self.active[name] == active:
            return []
        self.active[name] = active
        return [Issue(name, active, text)]


# The autopilot parameters that limit a bank setpoint (name, factor to degrees), by autopilot
ROLL_LIMIT_PARAMS: dict[int, tuple[tuple[str, float], ...]] = {
    3: (("ROLL_LIMIT_DEG", 1.0), ("LIM_ROLL_CD", 0.01)),  # ArduPilot (4.5 and later, older)
    12: (("FW_R_LIM", 1.0),),  # PX4 fixed-wing
}
BANK_LIMIT_MARGIN_DEG = 5.0  # needed bank this far above the limit before it is reported:
# in turbulence the median gain itself reads 0.61-0.64 for 0.70 (a real day, six ArduPlanes,
# the limit right at 42.5 deg: 45.7-46.8 deg asked three times in 900 s with 3 deg), while a
# limit set to the ideal coordinated bank (32.6) is 9-14 deg short
BANK_LIMIT_MIN_SAMPLES = 100  # gain samples (10 s at 10 Hz) before the gain is trusted
BANK_LIMIT_GRACE_S = 120.0  # s of commanding before it judges: while the formation acquires,
# the learnt gain reads low (six ArduPlanes: 0.5-0.65 for 0.70, up to 100 s after take-over)
BANK_LIMIT_HOLD_S = 30.0  # the finding must hold this long (s) to be said or cleared
BANK_LIMIT_WINDOW_S = 120.0  # s: the need is judged at the median gain over this window,
# sampled once a second (in turbulence the learnt gain swings 0.55-0.9 for tens of seconds:
# six ArduPlanes in 7.5 m/s and SIM_WIND_TURB 1.5 with the limit right raised it 20 times in
# 900 s at the gain of the moment; at the window's best gain, with the limit too low, it
# asked for 35-41 deg instead of 42.5 and cleared itself 3 times)


class BankLimitMonitor:
    """The autopilot's bank limit against the bank the mission's turn-rate limit needs.

    A bank setpoint ``phi`` turns the aircraft at ``gain g tan(phi) / V`` (the gain the
    companion learns, :class:`companion.link.shaping.Shaper`); ArduPlane clips ``phi`` to
    ROLL_LIMIT_DEG (PX4: FW_R_LIM). With a limit below ``atan(V omega / (g gain))`` the
    aircraft cannot fly the mission's turn-rate limit ``omega``, and a loop that needs it
    (a tight end in a strong wind) is flown wide, silently: ArduPlane SITL at 32.6 deg flew
    0.70 x 18 = 12.6 deg/s, and six aircraft in 7.5 m/s of wind read 18 m of cross-track
    p95 (docs/arduplane.md). This says so, once, with the limit that would do.

    Args:
        max_turn_rate_rad_s: the mission's turn-rate limit (rad/s).
    """

    NAME = "bank_limit_low"

    def __init__(self, max_turn_rate_rad_s: float) -> None:
        """No limit known yet."""
        self.max_turn_rate_rad_s = float(max_turn_rate_rad_s)
        self.limit_deg: float | None = None
        self.active = False
        self._since: float | None = None  # when the finding first differed from ``active``
        self._start: float | None = None  # the first check since commanding began (s)
        self._gains: deque[tuple[float, float]] = deque()  # (t s, gain), once a second
        self._median: float | None = None  # of _gains, while they do not change

    def reset(self) -> None:
        """Not commanding: the grace starts again at the next check (the finding stays)."""
        self._since = self._start = None
        self._gains.clear()
        self._median = None

    def _median_gain(self, t_s: float, gain: float) -> float:
        """The median gain of the last ``BANK_LIMIT_WINDOW_S``, sampled once a second (worked
        out again only when the window's samples change)."""
        g = self._gains
        if not g or t_s - g[-1][0] >= 1.0:
            g.append((t_s, gain))
            self._median = None
        while g[0][0] < t_s - BANK_LIMIT_WINDOW_S:
            g.popleft()
            self._median = None
        if self._median is None:
            self._median = statistics.median(x for _, x in g)
        return self._median

    def needed_deg(self, airspeed_m_s: float, gain: float) -> float:
        """The bank (deg) that turns at the mission's limit at ``airspeed_m_s`` (m/s) and
        ``gain`` (achieved per ``g tan(phi) / V``)."""
        return math.degrees(math.atan(airspeed_m_s * self.max_turn_rate_rad_s / (G_M_S2 * gain)))

    def update(self, t_s: float, airspeed_m_s: float, gain: float, samples: int) -> Issue | None:
        """One check at ``t_s`` (s) with the learnt ``gain`` from ``samples`` pairs at
        ``airspeed_m_s`` (m/s), judged at the median gain of the last ``BANK_LIMIT_WINDOW_S``
        past the grace; the transition, if any: a finding that held ``BANK_LIMIT_HOLD_S``
        (nothing until the limit and the gain are known, nor in the first
        ``BANK_LIMIT_GRACE_S`` of commanding and half a window after it: the acquisition's
        low gains, 0.5-0.55 on six ArduPlanes, count for nothing)."""
        if self._start is None:
            self._start = t_s
        if self.limit_deg is None or samples < BANK_LIMIT_MIN_SAMPLES:
            return None
        if not (math.isfinite(airspeed_m_s) and airspeed_m_s > 0 and gain > 0):
            return None
        if t_s - self._start < BANK_LIMIT_GRACE_S:
            return None
        gain = self._median_gain(t_s, gain)
        if t_s - self._gains[0][0] < BANK_LIMIT_WINDOW_S / 2:
            return None  # half a window of gains past the grace, at least
        need = self.needed_deg(airspeed_m_s, gain)
        low = need > self.limit_deg + BANK_LIMIT_MARGIN_DEG
        if low == self.active:
            self._since = None
            return None
        if self._since is None:
            self._since = t_s
        if t_s - self._since < BANK_LIMIT_HOLD_S:
            return None
        self.active, self._since = low, None
        lim = self.limit_deg
        if not low:
            return Issue(self.NAME, False, f"bank limit {lim:.1f} deg flies the mission's turns")
        can = gain * G_M_S2 * math.tan(math.radians(lim)) / airspeed_m_s
        return Issue(
            self.NAME,
            True,
            f"bank limit {lim:.1f} deg turns {math.degrees(can):.1f} of "
            f"{math.degrees(self.max_turn_rate_rad_s):.1f} deg/s: raise it to {need:.1f}",
        )
