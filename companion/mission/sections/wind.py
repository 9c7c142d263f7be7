"""The mission's ``wind`` section: the first guess of the day's wind."""

from __future__ import annotations

from companion.mission.model import WindSpec
from companion.mission.yamlnodes import MapReader


def parse_wind(m: MapReader) -> WindSpec:
    m.done(("speed_m_s", "from_deg", "gust_std_m_s"))
    return WindSpec(
        m.number("speed_m_s", lo=0.0, hi=100.0, what="a wind speed (m/s)"),
        m.number("from_deg", 0.0, lo=-360.0, hi=360.0, what="a direction (deg)"),
        m.number("gust_std_m_s", 0.0, lo=0.0, hi=20.0, what="a gust strength (m/s rms)"),
    )
