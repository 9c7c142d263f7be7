"""Run reports: metrics (docs/design.md §8) and plots from a run folder.

A run folder holds ``mission.yaml``, ``truth.csv`` and ``events.jsonl`` (written by
``companion simulate`` or ``companion fleet``).
"""
