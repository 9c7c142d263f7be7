"""The paper's guidance (shared pure layer): what turn rate and airspeed keep a UAV in its
slot of the time-splay formation.

* :mod:`companion.guidance.steering` -- the steering law (eq. 17-21, with docs/design.md §4's
  corrections) and the cross-track hold; the gains (:class:`~companion.guidance.steering.Gains`);
* :mod:`companion.guidance.formation` -- the splay command from the members' phases, the
  phase-holding airspeed, the slot-tracking command, the slots' sensitivity to the wind;
* :mod:`companion.guidance.virtual` -- the virtual particle a prosecutor shares while away.

Numbers in, numbers out: no sockets, no clocks, no files.
"""
