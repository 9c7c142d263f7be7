"""The mission on real ArduPlane firmware: ``companion fleet MISSION --autopilot arduplane``.

* :mod:`companion.sim.arduplane.sitl`: finding the ArduPlane SITL binary, free ports, starting
  one instance per vehicle and bringing it up over MAVLink (parameters from the mission,
  the perimeter upload, arming, TAKEOFF to the vehicle's altitude);
* :mod:`companion.sim.arduplane.world`: the process beside the firmware that plays the
  mission's intruder scenario with the simulator's :class:`sitl_model.world.World`, reports
  detections as each aircraft's camera (component 100) and logs the telemetry-derived truth;
* :mod:`companion.sim.arduplane.fleet`: :class:`ArduPlaneFleet`, the fleet run on those pieces.
"""
