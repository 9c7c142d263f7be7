"""Alerts (docs/design.md §5), pure: from a detection to its answer.

* :mod:`~companion.agent.alerts.record` -- one distinct alert as a companion keeps it;
* :mod:`~companion.agent.alerts.lifecycle` -- its status as a table keyed by (state, event);
* :mod:`~companion.agent.alerts.book` -- the alerts known: duplicates merged, memory bounded;
* :mod:`~companion.agent.alerts.tasking` -- who answers each queued alert, and when;
* :mod:`~companion.agent.alerts.prosecution` -- flying to the site and how it ends;
* :mod:`~companion.agent.alerts.paths` -- the minimum-time paths flown (to the site, to the
  slot, back over the site) and the geofence check.

The message itself is :class:`companion.group.messages.Alert`.
"""
