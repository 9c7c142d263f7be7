"""Mission files (YAML, version 1): parsing into typed frozen dataclasses.

``load_mission(path)`` is the one way in; every problem raises :class:`MissionError` naming
the file, the field, the line and what was expected.
"""

from companion.mission.errors import MissionError
from companion.mission.load import load_mission, parse_mission
from companion.mission.model import Intruder, Mission

__all__ = ["Intruder", "Mission", "MissionError", "load_mission", "parse_mission"]
