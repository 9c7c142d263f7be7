"""One companion process's edge: :mod:`~companion.process.runner` wires the autopilot link,
the group and the Agent in one selectors loop; :mod:`~companion.process.event_log` writes
``events.jsonl``."""
