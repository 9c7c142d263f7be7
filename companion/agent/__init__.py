"""One UAV's decisions (pure): :class:`companion.agent.agent.Agent` and its parts.

* :mod:`~companion.agent.agent` -- the Agent, a composition of typed parts: fed states,
  alerts, detections and its own state estimate (:mod:`~companion.agent.fix`) with the
  vehicle's time; returns the command, the state to share, alerts and events
  (:mod:`~companion.agent.output`, :mod:`~companion.agent.events`); its options are one
  :class:`~companion.agent.config.AgentConfig`;
* :mod:`~companion.agent.modes` -- its own mode as a table keyed by (state, event);
  :mod:`~companion.agent.away` -- each mode's record, made and dropped by the transitions;
  :mod:`~companion.agent.pilot` -- the mode's handler, picked by the mode;
* :mod:`~companion.agent.neighbours` -- who is in the formation; :mod:`~companion.agent.splay`
  -- flying the loop in it (:mod:`~companion.agent.formed`: formed, re-splay along the loop);
* :mod:`~companion.agent.alert_duty` -- the alerts it knows, raises and shares;
  :mod:`~companion.agent.alerts` -- the record and its lifecycle table, the book, tasking,
  prosecution, tracking, the paths flown;
* :mod:`~companion.agent.rejoin` -- flying back into its slot;
* :mod:`~companion.agent.wind` -- the fleet's one wind: agreement and following it;
* :mod:`~companion.agent.relief` -- the reliefs.

No sockets, no clocks, no files, no pymavlink; the Runner (:mod:`companion.process`) is its
edge.
"""
