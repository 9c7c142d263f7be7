"""The live patrol page (``companion dashboard``): a passive member of the signed group.

* :mod:`companion.dashboard.geometry` -- pure: the mission's fixed picture (``/api/mission``).
* :mod:`companion.dashboard.model` -- pure: the group's messages -> vehicles, alerts, gauges.
* :mod:`companion.dashboard.reliefs` -- pure: the members' batteries -> spares, the relief
  plan, late warnings (the model's reliefs part).
* :mod:`companion.dashboard.server` -- aiohttp: the page, ``/api/*`` and the group edge.
* ``static/index.html`` -- the page (one file, vanilla JS and SVG, no build step).

See ``docs/dashboard.md``.
"""
