"""Fleet key files and persisted signing timestamps (file I/O edge of the group).

* A key file holds the 32-byte MAVLink 2 signing key, as exactly 32 raw bytes or as 64
  hexadecimal characters (surrounding whitespace allowed). It must not be readable or
  writable by group or others: :func:`load_key` refuses it with a
  :class:`~companion.contracts.errors.UserError` that names the file and the fix (``chmod 600``).
* :func:`generate_key_file` writes a fresh random key (hex) with mode 0600, never over an
  existing file.
* :class:`TimestampFile` persists a sender's signing-timestamp upper bound (10 us units since
  2015-01-01 UTC, see :class:`companion.contracts.signing.Signing`) in a small text file, one per
  (key, system id), next to the key or in a given state directory. Written atomically
  (temporary file, fsync, rename), mode 0600.
"""

from __future__ import annotations

import hashlib
import os
import secrets
import stat
import time
from collections.abc import Callable
from pathlib import Path

from companion.contracts.errors import UserError
from companion.contracts.signing import GROUP_LINK_ID, Signing

__all__ = [
    "KEY_LEN",
    "TimestampFile",
    "generate_key_file",
    "key_fingerprint",
    "load_key",
    "signing_from_key_file",
    "timestamp_path",
]

KEY_LEN = 32  # bytes


def load_key(path: str | os.PathLike[str]) -> bytes:
    """The 32-byte key in ``path`` (raw or hex); refuses a file open to group/others."""
    p = Path(path)
    try:
        st = p.stat()
        if not stat.S_ISREG(st.st_mode):
            raise UserError(f"key file {p}: not a regular file")
        if st.st_mode & 0o077:
            raise UserError(
                f"key file {p} is accessible by group/others (mode "
                f"{stat.S_IMODE(st.st_mode):04o}); restrict it with: chmod 600 {p}"
            )
        data = p.read_bytes()
    except OSError as exc:
        raise UserError(f"cannot read key file {p}: {exc.strerror}") from None
    if len(data) == KEY_LEN:
        return data
    try:
        text = data.decode("ascii").strip()
        key = bytes.fromhex(text) if len(text) == 2 * KEY_LEN else b""
    except (UnicodeDecodeError, ValueError):
        key = b""
    if len(key) != KEY_LEN:
        raise UserError(
            f"key file {p}: expected {KEY_LEN} raw bytes or {2 * KEY_LEN} hex characters "
            f"(got {len(data)} bytes); make one with: companion keygen FILE"
        )
    return key


def generate_key_file(path: str | os.PathLike[str]) -> bytes:
    """Write a new random key to ``path`` as 64 hex characters and a newline, mode 0600.

    Refuses (``UserError``) to overwrite an existing file. Returns the key.
    """
    p = Path(path)
    key = secrets.token_bytes(KEY_LEN)
    try:
        fd = os.open(p, os.O_WRONLY | os.O_CREAT | os.O_EXCL, 0o600)
    except FileExistsError:
        raise UserError(f"{p} exists; refusing to overwrite a key file") from None
    except OSError as exc:
        raise UserError(f"cannot create key file {p}: {exc.strerror}") from None
    with os.fdopen(fd, "w", encoding="ascii") as f:
        os.fchmod(f.fileno(), 0o600)  # whatever the umask
        f.write(key.hex() + "\n")
        f.flush()
        os.fsync(f.fileno())
    return key


def key_fingerprint(key: bytes) -> str:
    """A short public identifier of a key (hex of the first 4 bytes of its SHA-256)."""
    return hashlib.sha256(b"patrol-group-key" + key).hexdigest()[:8]


def timestamp_path(
    key_file: str | os.PathLike[str],
    key: bytes,
    sysid: int,
    state_dir: str | os.PathLike[str] | None = None,
) -> Path:
    """Where the signing-timestamp bound of ``sysid`` under ``key`` lives.

    ``<state_dir or the key's directory>/<key file name>.<fingerprint>.sysid<N>.signing-ts``;
    the fingerprint gives a replaced key a fresh file.
    """
    k = Path(key_file)
    folder = Path(state_dir) if state_dir is not None else k.parent
    return folder / f"{k.name}.{key_fingerprint(key)}.sysid{sysid}.signing-ts"


class TimestampFile:
    """A :class:`~companion.contracts.signing.TimestampStore` in one small text file."""

    def __init__(self, path: str | os.PathLike[str]) -> None:
        """The store at ``path`` (created on the first :meth:`save`)."""
        self.path = Path(path)

    def load(self) -> int:
        """The persisted bound (10 us units since 2015), 0 if the file does not exist."""
        try:
            text = self.path.read_text(encoding="ascii").strip()
        except FileNotFoundError:
            return 0
        except (OSError, UnicodeDecodeError) as exc:
            raise UserError(f"cannot read signing state {self.path}: {exc}") from None
        if not text.isdigit():
            raise UserError(
                f"signing state {self.path} is corrupt ({text[:20]!r}); delete it to fall "
                "back to wall-clock timestamps"
            )
        return int(text)

    def save(self, timestamp: int) -> None:
        """Persist ``timestamp`` atomically and durably (temporary file, fsync, rename)."""
        tmp = self.path.with_name(f"{self.path.name}.{os.getpid()}.tmp")
        try:
            fd = os.open(tmp, os.O_WRONLY | os.O_CREAT | os.O_TRUNC, 0o600)
            with os.fdopen(fd, "w", encoding="ascii") as f:
                f.write(f"{timestamp}\n")
                f.flush()
                os.fsync(f.fileno())
            os.replace(tmp, self.path)
        except OSError as exc:
            raise UserError(f"cannot write signing state {self.path}: {exc.strerror}") from None


def signing_from_key_file(
    key_file: str | os.PathLike[str],
    sysid: int,
    *,
    state_dir: str | os.PathLike[str] | None = None,
    clock: Callable[[], float] = time.time,
    link_id: int = GROUP_LINK_ID,
) -> Signing:
    """Signing state for ``sysid`` with the key in ``key_file`` and its persisted timestamps.

    ``clock`` is the wall clock (unix s) that MAVLink signing timestamps follow.
    """
    key = load_key(key_file)
    store = TimestampFile(timestamp_path(key_file, key, sysid, state_dir))
    return Signing(key, clock, link_id=link_id, store=store)
