"""Companion computer software for coordinated perimeter patrol in wind.

Conventions (stated once, used everywhere; see docs/design.md §1):

* Local frame: horizontal NED. ``x`` = North (m), ``y`` = East (m); a point is the complex
  number ``r = x + i y``.
* Angles are compass angles: measured from North towards East, so ``exp(i gamma)`` is the
  unit vector (cos gamma North, sin gamma East). A positive turn rate is a right turn
  (clockwise seen from above).
* SI units and radians inside; degrees only at the edges, with the unit in the name.
* Wind is given by its speed and the direction it blows FROM.
"""

__version__ = "0.1.0"
