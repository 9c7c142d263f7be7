"""The MAVLink mission protocol, client side: the perimeter and the fence up to an autopilot
and verified, the mission read back from it.

* :mod:`~companion.link.mission_protocol.client` -- the protocol itself, sans-IO (messages and
  time in, messages out), the mirror of :mod:`sitl_model.mission_protocol`; likewise
  :mod:`~companion.link.mission_protocol.params` (a parameter read or set) and
  :mod:`~companion.link.mission_protocol.listen` (the autopilots on a link);
* :mod:`~companion.link.mission_protocol.driver` -- the one loop that runs them over a
  pymavlink connection;
* :mod:`~companion.link.mission_protocol.transfer` -- items up and down, the perimeter
  uploaded and verified;
* :mod:`~companion.link.mission_protocol.vehicle` -- one vehicle's perimeter and fence
  (``companion upload``, the fleet's uploads);
* :mod:`~companion.link.mission_protocol.fence` -- the fence items and parameters;
* :mod:`~companion.link.mission_protocol.home_slot` -- where each autopilot keeps home;
* :mod:`~companion.link.mission_protocol.from_autopilot` -- a mission from the autopilot's
  stored loop (``companion run`` without ``--mission``).
"""
