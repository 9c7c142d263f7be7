"""Reliefs (pure; docs/energy.md): when a UAV on station must leave, which spare relieves
whom, and one UAV's part in it.

* ``energy.py`` -- the time a UAV must leave for home: its battery to the reserve, less the
  flight home in the agreed wind (vehicle s, mAh, A); the battery as reported.
* ``schedule.py`` -- the fleet's reliefs, computed the same way by every member from the
  shared states: which spare relieves which member, when it launches, and which reliefs
  will be late (announced before they are); ``roster.py`` -- who may take part, the
  bases, the rotation's beat.
* ``duty.py`` -- one UAV's part, the seam the Agent calls: four states along
  ``states.DUTY_TABLE``, each with its record (``records.py``); a relieving spare's and a
  relieved UAV's stages along ``states.RELIEVING_TABLE`` and ``states.HOME_TABLE``, flown
  by ``fly_in.py`` and ``fly_home.py`` over the geometry of ``join.py``; ``on_station.py``,
  ``relieving.py`` and ``planning.py`` the rest of what it decides; ``events.py`` what it
  says.

Imports nothing of its package here.
"""
