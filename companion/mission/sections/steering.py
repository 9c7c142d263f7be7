"""The mission's ``steering`` section: the steering law's gains (defaults where left out)."""

from __future__ import annotations

from companion.guidance.steering import Gains
from companion.mission.model import CENTRE_FORMS
from companion.mission.yamlnodes import MapReader


def parse_steering(m: MapReader) -> Gains:
    m.done(
        (
            "centre_gain",
            "phase_gain",
            "centre_form",
            "track_gain",
            "speed_authority_m_s",
            "speed_tau_s",
            "xtrack_bw_rad_s",
            "xtrack_damping",
        )
    )
    d = Gains()
    return Gains(
        centre_gain=m.number("centre_gain", d.centre_gain, lo=0.0, hi=1e3, lo_open=True),
        phase_gain=m.number("phase_gain", d.phase_gain, lo=0.0, hi=1e3, lo_open=True),
        centre_form=m.choice("centre_form", d.centre_form, CENTRE_FORMS),
        track_gain=m.number("track_gain", d.track_gain, lo=0.0, hi=1e3, lo_open=True),
        speed_authority_m_s=m.number(
            "speed_authority_m_s",
            d.speed_authority_m_s,
            lo=0.0,
            hi=10.0,
            what="an airspeed authority (m/s)",
        ),
        speed_tau_s=m.number(
            "speed_tau_s", d.speed_tau_s, lo=1.0, hi=600.0, what="a time constant (s)"
        ),
        xtrack_bw_rad_s=m.number(
            "xtrack_bw_rad_s", d.xtrack_bw_rad_s, lo=0.0, hi=2.0, what="a bandwidth (rad/s)"
        ),
        xtrack_damping=m.number("xtrack_damping", d.xtrack_damping, lo=0.0, hi=10.0, lo_open=True),
    )
