"""A run as MCAP, for Foxglove and the other tools that read it (``companion export``).

* :mod:`companion.export.runfolder` -- edge: reads a run folder (``truth.csv``,
  ``events.jsonl``, ``uavN/autopilot.tlog``, ``mission.yaml``, ``metrics.json``) or a real
  companion's log folder (``autopilot.tlog``, ``events.jsonl``), in vehicle time.
* :mod:`companion.export.model` -- pure: what is read (truth, tlog messages, events) as
  records, and the vehicle-time rule.
* :mod:`companion.export.foxglove` -- pure: Foxglove's well-known JSON schemas
  (LocationFix, PoseInFrame, FrameTransform, GeoJSON, Log) and messages in them.
* :mod:`companion.export.topics` -- pure: the run -> topics and messages (the table);
  :mod:`companion.export.vehicles` -- pure: each UAV's topics.
* :mod:`companion.export.mcap_file` -- edge: writes the MCAP file (the ``mcap`` package).

See ``docs/export.md``.
"""
