"""The mission file's sections, one module per top-level key, each read by
:mod:`companion.mission.load`: ``origin`` (and the points given relative to it),
``perimeter`` (and whether its loop is flyable), ``wind``, ``steering``, ``vehicles``
(battery, spares, the relief rotation), ``scenario`` (duration, intruders) and ``fence``. The
``sensor`` section, one number, is read by the loader itself.
"""
