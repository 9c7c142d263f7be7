"""The fleet's one wind (pure): every member flies by the same agreed wind.

* :mod:`~companion.agent.wind.agreement` -- members' estimates in, an agreed record out;
* :mod:`~companion.agent.wind.follow` -- one member following the agreement: the loop
  re-timed, rate-limited proposals, ``loop_infeasible``.

Its own estimate comes from the autopilot link (:mod:`companion.link.wind_estimate`).
"""
