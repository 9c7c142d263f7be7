"""The companion's link to its own autopilot (docs/design.md §7), split pure / I/O.

* :mod:`companion.link.setpoints` -- pure: a turn-rate command -> the MAVLink setpoint of a
  profile (turn rate, bank angle, course), and back (for tests and logs).
* :mod:`companion.link.shaping` -- pure: closes the loop on the measured course rate for the
  bank and heading profiles (online efficiency / course-hold gain estimates).
* :mod:`companion.link.clock` -- pure: vehicle time from SYSTEM_TIME and ``time_boot_ms``.
* :mod:`companion.link.estimate` -- pure: state estimate (position, course, air heading) from
  GLOBAL_POSITION_INT, and the measured course rate.
* :mod:`companion.link.battery` -- pure: the battery estimate (remaining %, consumed mAh,
  voltage) from SYS_STATUS and BATTERY_STATUS; bad reports ignored and counted.
* :mod:`companion.link.modes` -- pure: ArduPlane modes and the command-authority state
  machine (waiting / commanding / overridden / link lost).
* :mod:`companion.link.px4` -- pure: PX4's modes (OFFBOARD) and the OFFBOARD entry (pre-stream,
  back-off, giving up); :mod:`companion.link.offboard` -- pure: PX4's two offboard setpoint
  profiles (attitude with the companion's own height and airspeed hold; path).
* :mod:`companion.link.targets` -- pure: the GUIDED airspeed and altitude targets (returned,
  with their events, for the process to send).
* :mod:`companion.link.outbox` -- pure: what the companion asks its link to send, as data
  (STATUSTEXT, COMMAND_LONG, built messages); :mod:`companion.link.events` -- pure: the typed
  events of the link and the process (the record shape of ``events.jsonl``).
* :mod:`companion.link.tlog` -- the .tlog writer (both directions).
* :mod:`companion.link.connection` -- the pymavlink connection as component 191: heartbeat,
  message intervals, reconnect; the one place bytes cross the autopilot link;
  :mod:`companion.link.serial_device` -- a serial port that never blocks, prints or spins
  (a pulled cable re-opened, a cut wire waited out).

Conventions: local NED at the mission origin, positions complex ``north + i east`` (m),
compass angles (rad inside, deg at the edges), positive turn rate = right turn.
"""
