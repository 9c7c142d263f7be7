"""A MAVLink 2 simulator of N fixed-wing autopilots flying the constant-speed particle in wind.

Conventions as in :mod:`companion`: local NED with complex positions ``north + i east`` (m),
compass angles (rad inside, deg at the edges), positive turn rate = right turn.
"""

__version__ = "0.1.0"
