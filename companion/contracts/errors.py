"""Error types shared across the companion.

``UserError`` (a ``ValueError``) is bad input from the user: a mission file, a flag, a
request line. The command line prints it as one line and exits with status 2.
"""

from __future__ import annotations


class UserError(ValueError):
    """Bad input from the user; its message is shown as is, without a traceback."""
