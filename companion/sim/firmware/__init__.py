"""What real-firmware fleets share (ArduPlane and PX4 SITL, ``companion fleet --autopilot``).

* :mod:`companion.sim.firmware.world`: the process beside the firmware that plays the
  mission's intruder scenario with the simulator's :class:`sitl_model.world.World`, reports
  detections as each aircraft's camera (component 100), logs the telemetry-derived truth and
  disciplines the instances' clocks; each autopilot supplies its link, its clock source and its
  speed actuator (:mod:`companion.sim.arduplane.world`, :mod:`companion.sim.px4.world`).
"""
