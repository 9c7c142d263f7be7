"""Pure guidance core, and with it the shared pure layer (docs/architecture.md, the rule).

With :mod:`companion.mission`, :mod:`companion.planner` and :mod:`companion.contracts.errors`,
what the
companion and the simulator (``sitl_model``) both build on: numbers in, numbers out. No
sockets, no asyncio, no pymavlink, no clocks, no files, no processes; it imports nothing of
``companion`` outside the shared layer and nothing of ``sitl_model`` (tests/test_layers.py).
"""
