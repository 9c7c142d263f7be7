"""The in-memory engine (``companion simulate``): the simulator's vehicles and N real
companions, lockstepped in one process. :mod:`companion.sim.inmemory.engine` steps them;
:mod:`companion.sim.inmemory.wires` holds the queues that replace their sockets."""

from companion.sim.inmemory.engine import Engine, EngineConfig
from companion.sim.inmemory.wires import BusSocket, GroupBus, MemoryConn, VehiclePort, fleet_key

__all__ = [
    "BusSocket",
    "Engine",
    "EngineConfig",
    "GroupBus",
    "MemoryConn",
    "VehiclePort",
    "fleet_key",
]
