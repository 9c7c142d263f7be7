"""The mission on real PX4 firmware (SITL, fixed-wing SIH): ``companion fleet MISSION
--autopilot px4``.

* :mod:`companion.sim.px4.sitl`: finding the PX4 SITL folder, free instance numbers,
  starting and stopping one instance per vehicle;
* :mod:`companion.sim.px4.params`: the mission's parameters of each instance and its take-off
  altitude;
* :mod:`companion.sim.px4.bringup`: bringing every instance up over its ground-station link
  (the perimeter and fence upload, OFFBOARD on the ground, AUTO.TAKEOFF, arming, AUTO.LOITER
  at the vehicle's altitude; a used battery's charge);
* :mod:`companion.sim.px4.world`: the world process of :mod:`companion.sim.firmware.world`
  on each instance's camera link, the clocks kept together by pausing the instances ahead;
* :mod:`companion.sim.px4.fleet`: :class:`Px4Fleet`, the fleet run on those pieces.
"""
