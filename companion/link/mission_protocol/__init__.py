"""The MAVLink mission protocol, client side: the perimeter and the fence up to an autopilot
and verified, the mission read back from it.

* :mod:`~companion.link.mission_protocol.transfer` -- items up and down;
* :mod:`~companion.link.mission_protocol.vehicle` -- one vehicle's perimeter and fence
  (``companion upload``, the fleet's uploads);
* :mod:`~companion.link.mission_protocol.fence` -- the fence items and parameters;
* :mod:`~companion.link.mission_protocol.home_slot` -- where each autopilot keeps home;
* :mod:`~companion.link.mission_protocol.from_autopilot` -- a mission from the autopilot's
  stored loop (``companion run`` without ``--mission``).
"""
