"""One UAV's decisions (pure): :class:`companion.agent.agent.Agent` and its seams.

* :mod:`~companion.agent.agent` -- the Agent: fed states, alerts, detections and its own
  state estimate with the vehicle's time; returns the command, the state to share, alerts
  and events (:mod:`~companion.agent.output`, :mod:`~companion.agent.events`);
* :mod:`~companion.agent.modes` -- its own mode as a table keyed by (state, event);
* :mod:`~companion.agent.neighbours` -- who is in the formation;
* :mod:`~companion.agent.alerts` -- alerts: the record and its lifecycle table, the book,
  tasking, prosecution, the paths flown;
* :mod:`~companion.agent.rejoin` -- flying back into its slot (:mod:`~companion.agent.away`
  is the working state while away);
* :mod:`~companion.agent.wind` -- the fleet's one wind: agreement and following it.

No sockets, no clocks, no files, no pymavlink; the Runner (:mod:`companion.process`) is its
edge.
"""
