"""Reliefs (pure; docs/energy.md): when a UAV on station must leave, and which spare
relieves whom.

* ``energy.py`` -- the time a UAV must leave for home: its battery to the reserve, less the
  flight home in the agreed wind (vehicle s, mAh, A).
* ``schedule.py`` -- the fleet's reliefs, computed the same way by every member from the
  shared states: which spare relieves which member, when it launches, and which reliefs
  will be late (announced before they are).

Imports nothing of its package here.
"""
