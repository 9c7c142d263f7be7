"""The one error type of mission parsing."""

from __future__ import annotations

from companion.contracts.errors import UserError


class MissionError(UserError):
    """A mission file is unreadable or invalid.

    The message reads ``FILE:LINE: FIELD: problem (expected ...)`` so an editor can jump to it.

    Attributes:
        file: the mission file's path as given.
        field: dotted path of the offending field (e.g. ``vehicles.airspeed_m_s``), or "".
        line: 1-based line in the file, or None when unknown.
    """

    def __init__(self, file: str, field: str, message: str, line: int | None = None) -> None:
        """Build the error; see the class docstring for the arguments."""
        self.file = file
        self.field = field
        self.line = line
        self.problem = message
        where = f"{file}:{line}" if line is not None else file
        what = f" {field}:" if field else ""
        super().__init__(f"{where}:{what} {message}")

    def __reduce__(self) -> tuple:
        """Pickled with its own arguments, so it crosses to another process whole (a pool's
        or a Dask worker's error); the default pickles only the message and fails."""
        return (type(self), (self.file, self.field, self.problem, self.line))
