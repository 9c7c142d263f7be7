"""What the companion and the simulator agree on, beyond the maths (shared pure layer).

* :mod:`companion.contracts.errors` -- :class:`~companion.contracts.errors.UserError`, the
  base of every "bad input" error (exit status 2, one line, no traceback);
* :mod:`companion.contracts.signing` -- MAVLink 2 signing state, the frame check, link ids;
* :mod:`companion.contracts.simulator` -- the simulator's epoch, port spacing, truth-log
  columns;
* :mod:`companion.contracts.attitude_target` -- how ArduPlane reads a SET_ATTITUDE_TARGET mask;
* :mod:`companion.contracts.argv` -- negative option values on both command lines.

No sockets, no clocks, no files; imports nothing of ``companion`` outside the shared layer.
"""
