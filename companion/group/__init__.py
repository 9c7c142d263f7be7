"""The companions' group: signed MAVLink 2 over UDP multicast (DESIGN section 7).

* :mod:`companion.group.dialect` -- the ``patrol.xml`` dialect, generated on import.
* :mod:`companion.group.codec` -- pure: states/alerts <-> datagrams, signing, drop reasons.
* :mod:`companion.group.keys` -- key files and persisted signing timestamps.
* :mod:`companion.group.faults` -- loss, jitter, duplication, reordering on send.
* :mod:`companion.group.transport` -- the socket: :class:`Group`.

The wire format is documented in ``docs/protocol.md``.
"""

from companion.group.codec import Decoder, Dropped, EncodeError, Signing, encode
from companion.group.faults import FaultModel
from companion.group.keys import generate_key_file, load_key, signing_from_key_file
from companion.group.transport import Group, parse_group

__all__ = [
    "Decoder",
    "Dropped",
    "EncodeError",
    "FaultModel",
    "Group",
    "Signing",
    "encode",
    "generate_key_file",
    "load_key",
    "parse_group",
    "signing_from_key_file",
]
