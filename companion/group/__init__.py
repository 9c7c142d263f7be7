"""The companions' group: signed MAVLink 2 over UDP multicast (docs/design.md §7).

* :mod:`companion.group.dialect` -- the ``patrol.xml`` dialect, generated on import.
* :mod:`companion.group.codec` -- pure: states/alerts <-> datagrams, drop reasons (the
  signing state is :class:`companion.contracts.signing.Signing`).
* :mod:`companion.group.keys` -- key files and persisted signing timestamps.
* :mod:`companion.group.faults` -- loss, jitter, duplication, reordering on send.
* :mod:`companion.group.transport` -- the socket: :class:`~companion.group.transport.Group`.

The package imports none of them, so ``sitl-model`` can read a key file with
:mod:`companion.group.keys` without loading the rest. The wire format is documented in
``docs/protocol.md``.
"""
