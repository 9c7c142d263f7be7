"""The composition roots that run a simulator beside real companions (the only part of
``companion`` that imports ``sitl_model``):

* :mod:`companion.sim.inmemory` -- ``companion simulate``: the simulator and N Runners in one
  process, lockstepped, deterministic;
* :mod:`companion.sim.fleet` -- ``companion fleet``: ``sitl-model`` and one ``companion run``
  per UAV as processes over loopback UDP;
* :mod:`companion.sim.arduplane` -- ``companion fleet --autopilot arduplane``: real ArduPlane
  SITL instances instead of the simulator.
"""
