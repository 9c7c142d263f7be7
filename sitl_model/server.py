"""Where bytes enter and leave the simulator: UDP sockets, stdin control, logs, pacing.

One UDP socket per vehicle (``host:base_port + 10 i``), all in one single-threaded
``selectors`` loop. Simulated time advances in fixed physics steps paced against the wall
clock times ``speedup``; when the machine cannot keep up, the lag (wall s behind schedule)
is reported in the status line and the simulation catches up as fast as it can. Every
peer that has sent a valid MAVLink message to a vehicle receives its telemetry, a step's
frames together in one datagram, until it has been silent for ``PEER_SILENCE_S`` wall
seconds; replies to requests go to the requester only. SIGINT/SIGTERM end the loop cleanly.

With a link signing key (``--signing-key-file``) every vehicle endpoint signs what it sends
(link id :data:`~companion.contracts.signing.VEHICLE_LINK_ID`) and acts only on correctly signed
frames with a fresh timestamp per (sysid, compid, link id) stream; the others are dropped and
counted (``unsigned``, ``bad_signature``, ``replayed``: status line, ``link_rejected`` events).
Their sender still becomes a peer and receives telemetry, as on ArduPilot, where signing
authenticates commands and does not hide the downlink.

With ``--lockstep`` the physics waits, before each step, for every vehicle that the
:class:`sitl_model.lockstep.LockstepGate` says must answer its latest GLOBAL_POSITION_INT
(in GUIDED, with a live controlling peer), at most ``--lockstep-wait`` wall seconds each;
``--speedup`` is then a ceiling, never caught up after a wait (docs/sitl.md, "Lockstep").
The lockstepped physics steps at the companions' control period, 0.1 s at once
(:meth:`sitl_model.sim.Simulation.advance`; ``--physics-hz``), free running at 50 Hz.
"""

from __future__ import annotations

import contextlib
import json
import os
import random
import resource
import selectors
import signal
import socket
import sys
import time
from collections.abc import Callable
from dataclasses import dataclass
from typing import Any, TextIO

from companion.contracts.signing import VEHICLE_LINK_ID, FrameCheck, Signing
from companion.contracts.simulator import PORT_SPACING
from sitl_model.autopilot import Mode
from sitl_model.codec import MAV_COMP_ID_AUTOPILOT1, MAV_COMP_ID_CAMERA, Decoder, Encoder
from sitl_model.link import Counters, VehicleLink
from sitl_model.lockstep import DEFAULT_WAIT_BOUND_S, LockstepGate
from sitl_model.operator_input import HELP, ControlError, parse_line
from sitl_model.outputs import after_step
from sitl_model.sim import DT_S, SENSOR_EVERY, Simulation

MAX_PEERS = 16
PEER_SILENCE_S = 30.0  # wall s without a message after which a peer gets nothing more
MAX_DATAGRAM = 1400  # bytes of frames sent in one datagram at most (below a path's MTU)
BATCH_WALL_S = 0.01  # service sockets at least this often while catching up
# what a companion tells its ground stations, forwarded to every other peer (docs/protocol.md):
# its texts and values, and its health (HEARTBEAT, ONBOARD_COMPUTER_STATUS: docs/gcs.md)
RELAYED = frozenset({
    "STATUSTEXT", "NAMED_VALUE_FLOAT", "NAMED_VALUE_INT", "HEARTBEAT", "ONBOARD_COMPUTER_STATUS",
})  # fmt: skip
REJECT_EVENT_WALL_S = 1.0  # at most one link_rejected event per vehicle per wall second
LOCKSTEP_SLACK_S = 0.1  # lockstep: simulated s the pace may trail (then re-anchored there)


@dataclass
class ServerConfig:
    """I/O settings: ports, pacing, outputs. ``duration_s`` (simulated) None = forever."""

    host: str = "127.0.0.1"
    base_port: int = 5760
    speedup: float = 1.0
    gcs_out: tuple[tuple[str, int], ...] = ()
    truth_log: str | None = None
    events_log: str | None = None
    status_interval_s: float = 5.0
    duration_s: float | None = None
    control_stdin: bool = True
    signing_key: bytes | None = None  # 32-byte link signing key, one for every vehicle
    lockstep: bool = False  # step only when the controlled vehicles have answered
    lockstep_wait_s: float = DEFAULT_WAIT_BOUND_S  # wall s waited for one answer at most
    physics_every: int = 1  # physics steps of DT_S taken at once (1 or SENSOR_EVERY)


class Server:
    """Runs a :class:`Simulation` behind its MAVLink links until stopped."""

    def __init__(
        self,
        sim: Simulation,
        links: list[VehicleLink],
        cfg: ServerConfig,
        wall: Callable[[], float] = time.monotonic,
        err: TextIO = sys.stderr,
        out: TextIO = sys.stdout,
    ) -> None:
        """Bind the sockets (raises ``OSError`` if a port is taken; ``ValueError`` if
        ``physics_every`` does not divide ``SENSOR_EVERY``)."""
        if cfg.physics_every < 1 or SENSOR_EVERY % cfg.physics_every:
            raise ValueError(f"physics_every must divide {SENSOR_EVERY}: {cfg.physics_every}")
        self.sim, self.links, self.cfg = sim, links, cfg
        self.wall, self.err, self.out = wall, err, out
        self.running = True
        self.sel = selectors.DefaultSelector()
        self.socks: list[socket.socket] = []
        self.peers: list[dict[Any, float]] = [{} for _ in links]
        self.signing = cfg.signing_key is not None
        self.enc: list[Encoder] = []
        self.cam: list[Encoder] = []
        self.decoders: list[Decoder] = []  # per vehicle: its own signing stream table
        for s in sim.sysids:
            check = _frame_check(cfg.signing_key)
            self.enc.append(Encoder(s, MAV_COMP_ID_AUTOPILOT1, check))
            self.cam.append(Encoder(s, MAV_COMP_ID_CAMERA, check))
            self.decoders.append(Decoder(check))
        self._reject_logged: list[tuple[int, float]] = [(0, -1e9) for _ in links]
        self.gcs_out = list(cfg.gcs_out)
        self.dropped_send = 0
        self.lag_s = 0.0
        self._rtf = 0.0
        self._stdin_was_blocking: bool | None = None
        self.gate = LockstepGate(len(links), cfg.lockstep_wait_s) if cfg.lockstep else None
        try:
            for i in range(len(links)):
                s = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
                s.setblocking(False)
                s.setsockopt(socket.SOL_SOCKET, socket.SO_SNDBUF, 1 << 20)
                s.setsockopt(socket.SOL_SOCKET, socket.SO_RCVBUF, 1 << 20)
                s.bind((cfg.host, cfg.base_port + PORT_SPACING * i))
                self.socks.append(s)
                self.sel.register(s, selectors.EVENT_READ, i)
        except OSError:
            self.close()
            raise
        self._stdin_buf = b""
        self._new_speed: float | None = None  # set by a "speedup X" control line
        if cfg.control_stdin:
            try:
                self._stdin_was_blocking = os.get_blocking(0)
                os.set_blocking(0, False)
                self.sel.register(0, selectors.EVENT_READ, "stdin")
            except (OSError, ValueError):
                pass
        self.truth = open(cfg.truth_log, "w", buffering=1 << 16) if cfg.truth_log else None  # noqa: SIM115
        if self.truth:
            self.truth.write(sim.truth_header + "\n")
        self.events = open(cfg.events_log, "w", buffering=1 << 14) if cfg.events_log else None  # noqa: SIM115

    # ------------------------------------------------------------------------ sending
    def _send(self, i: int, msgs: list[tuple[Any, Any]], camera: bool = False) -> None:
        enc = self.cam[i] if camera else self.enc[i]
        sock = self.socks[i]
        c = self.links[i].counters
        for msg, peer in msgs:
            data = enc.pack(msg)
            # a --gcs-out address that also talks to the vehicle is a peer too: send once
            everyone = dict.fromkeys([*self.peers[i], *self.gcs_out])
            dests = [peer] if peer is not None else list(everyone)
            for addr in dests:
                try:
                    sock.sendto(data, addr)
                    c.tx += 1
                except OSError:
                    self.dropped_send += 1

    def _send_datagrams(self, i: int, frames: list[bytes]) -> None:
        """Vehicle ``i``'s frames to every peer and ``--gcs-out`` address, as few datagrams
        as fit (frames kept whole and in order, at most ``MAX_DATAGRAM`` bytes each): a
        step's telemetry in one datagram, as ArduPilot fills a UDP packet."""
        sock = self.socks[i]
        c = self.links[i].counters
        dests = list(dict.fromkeys([*self.peers[i], *self.gcs_out]))
        start = 0
        while start < len(frames):
            end, size = start, 0
            while end < len(frames) and (end == start or size + len(frames[end]) <= MAX_DATAGRAM):
                size += len(frames[end])
                end += 1
            data = b"".join(frames[start:end])
            for addr in dests:
                try:
                    sock.sendto(data, addr)
                    c.tx += end - start
                except OSError:
                    self.dropped_send += 1
            start = end

    def _forget_silent_peers(self, now: float) -> None:
        """Stop sending to peers heard from last more than ``PEER_SILENCE_S`` wall s ago (a
        finished upload, a closed ground station; a live one sends a heartbeat a second)."""
        for peers in self.peers:
            if peers and min(peers.values()) < now - PEER_SILENCE_S:
                for addr in [a for a, t in peers.items() if t < now - PEER_SILENCE_S]:
                    del peers[addr]

    # ----------------------------------------------------------------------- receiving
    def _receive(self, i: int) -> None:
        sock = self.socks[i]
        link = self.links[i]
        now = self.wall()
        for _ in range(256):
            try:
                data, addr = sock.recvfrom(65535)
            except (BlockingIOError, InterruptedError):
                return
            except OSError:  # e.g. ICMP port unreachable reported on a later call
                continue
            decoder = self.decoders[i]
            msgs, bad = decoder.decode(data)
            link.counters.bad += bad
            link.tm.errors_comm[i] += bad
            for r in decoder.rejected:
                setattr(link.counters, r.reason, getattr(link.counters, r.reason) + 1)
            if not msgs and not decoder.rejected:
                continue
            peers = self.peers[i]
            if addr not in peers and len(peers) >= MAX_PEERS:
                del peers[min(peers, key=peers.__getitem__)]
            peers[addr] = now
            answered = link.setpoints_rx
            for m in msgs:
                if m.get_type() in RELAYED:
                    self._relay(i, m, addr)
                outs = link.handle(m, addr, now)
                if outs:
                    self._send(i, outs)
            if self.gate is not None and link.setpoints_rx != answered:
                self.gate.setpoint(i)
            self._log_mission_events(i)

    def _relay(self, i: int, m: Any, sender: Any) -> None:
        """Forward a companion's STATUSTEXT / NAMED_VALUE_* / HEARTBEAT /
        ONBOARD_COMPUTER_STATUS (verbatim, signature and all)
        to vehicle ``i``'s other peers and the ``--gcs-out`` addresses, as ArduPilot's
        routing forwards what it hears on one link to the others."""
        data = bytes(m.get_msgbuf())
        for addr in dict.fromkeys([*self.peers[i], *self.gcs_out]):
            if addr == sender:
                continue
            try:
                self.socks[i].sendto(data, addr)
                self.links[i].counters.tx += 1
            except OSError:
                self.dropped_send += 1

    def _log_rejects(self, i: int, now: float) -> None:
        """A ``link_rejected`` event when vehicle ``i`` refused frames since the last one."""
        c = self.links[i].counters
        total = c.unsigned + c.bad_signature + c.replayed
        logged, at = self._reject_logged[i]
        if total != logged and now - at >= REJECT_EVENT_WALL_S:
            self._reject_logged[i] = (total, now)
            counts = {r: getattr(c, r) for r in ("unsigned", "bad_signature", "replayed")}
            self._event(self.sim.t_s, "link_rejected", self.sim.sysids[i], counts)

    def _log_mission_events(self, i: int) -> None:
        mp = self.links[i].missions
        if mp.events:
            for name, data in mp.events:
                self._event(self.sim.t_s, name, self.sim.sysids[i], data)
            mp.events.clear()

    def _stdin(self) -> None:
        try:
            chunk = os.read(0, 4096)
        except BlockingIOError:
            return
        if not chunk:
            self.sel.unregister(0)
            return
        self._stdin_buf += chunk
        while b"\n" in self._stdin_buf:
            raw, self._stdin_buf = self._stdin_buf.split(b"\n", 1)
            self.out.write(self._control(raw.decode("utf-8", "replace")) + "\n")
            self.out.flush()

    def _control(self, line: str) -> str:
        try:
            cmd = parse_line(line, self.sim.t_s)
            if cmd.verb == "intruder" and cmd.intruder is not None:
                self.sim.add_intruder(cmd.intruder)
                return f"ok intruder {cmd.intruder.id} t_s={self.sim.t_s:.2f}"
            if cmd.verb == "speedup" and cmd.speedup is not None:
                self._new_speed = cmd.speedup  # the loop re-anchors its pacing on it
                return f"ok speedup {cmd.speedup:g} t_s={self.sim.t_s:.2f}"
            if cmd.verb == "status":
                return "ok " + self.status_line()
            if cmd.verb == "help":
                return "ok " + HELP
            return "ok"
        except (ControlError, ValueError) as e:
            return f"error: {e}"

    # --------------------------------------------------------------------------- logs
    def _event(self, t_s: float, event: str, sysid: int | None, data: dict) -> None:
        if self.events:
            rec = {"t_s": round(t_s, 3), "event": event}
            if sysid is not None:
                rec["sysid"] = sysid
            rec.update(data)
            self.events.write(json.dumps(rec) + "\n")

    def _after_step(self) -> None:
        """Send and log what the step emitted (:func:`sitl_model.outputs.after_step`, the
        same outputs as the in-memory engine's)."""
        out = after_step(self.sim, self.links)
        if self.events:
            for rec in out.events:
                self.events.write(json.dumps(rec) + "\n")
        gate = self.gate
        frames: dict[int, list[bytes]] = {}  # vehicle index -> this step's frames, in order
        positions: list[int] = []
        for i, msg, camera in out.sends:
            if not (self.peers[i] or self.gcs_out):
                continue
            frames.setdefault(i, []).append((self.cam[i] if camera else self.enc[i]).pack(msg))
            if gate is not None and self.peers[i] and msg.get_type() == "GLOBAL_POSITION_INT":
                positions.append(i)
        for i, batch in frames.items():  # one datagram per peer: the step's frames together
            self._send_datagrams(i, batch)
        for i in positions:  # the answer is due once the position report has left
            gate.position_sent(i, self.wall())
        if self.truth and out.truth:
            self.truth.write("\n".join(out.truth) + "\n")

    # ---------------------------------------------------------------------------- loop
    def totals(self) -> Counters:
        """Counters summed over all vehicles."""
        tot = Counters()
        for link in self.links:
            tot.add(link.counters)
        return tot

    def status_line(self) -> str:
        """One line: simulated time, real-time factor, lag, packet and refusal counts."""
        c = self.totals()
        ru = resource.getrusage(resource.RUSAGE_SELF)
        signing = (
            f" unsigned={c.unsigned} bad_signature={c.bad_signature} replayed={c.replayed}"
            if self.signing
            else ""
        )
        g = self.gate
        lockstep = f" lockstep_timeouts={g.timeouts} lockstep_wait={g.waited_s:.1f}s" if g else ""
        return (
            f"sitl t={self.sim.t_s:.1f}s rtf={self._rtf:.1f} lag={self.lag_s:.2f}s "
            f"rx={c.rx} tx={c.tx} bad={c.bad} foreign={c.foreign} refused={c.refused} "
            f"unsupported={c.unsupported}{signing}{lockstep} send_fail={self.dropped_send} "
            f"peers={sum(len(p) for p in self.peers)} cpu={ru.ru_utime + ru.ru_stime:.1f}s"
        )

    def _guided(self) -> list[bool]:
        """Per vehicle: in GUIDED and in the air, so the lockstep may wait for its answer. A
        vehicle on the ground (a spare waiting, a UAV that has landed) is not steered: its
        companion sends no setpoint there, and waiting for one cost a lockstep time-out at
        every landing; from its take-off its next setpoint makes it live again."""
        grounded = self.sim.grounded
        return [
            ap.mode is Mode.GUIDED and not grounded[i] for i, ap in enumerate(self.sim.autopilots)
        ]

    def _held(self) -> bool:
        """Lockstep: whether the next step must wait for an answer (timeouts logged)."""
        held, timed_out = self.gate.blocked(self.wall(), self._guided())
        for w in timed_out:
            sysid = self.sim.sysids[w.index]
            self._event(
                self.sim.t_s,
                "lockstep_wait_timeout",
                sysid,
                {"waited_wall_s": round(w.waited_s, 3), "bound_wall_s": self.gate.wait_bound_s},
            )
        return held

    def _steps_now(self) -> int:
        """Physics steps to take at once: ``physics_every``, single steps to end a
        ``duration_s`` that falls between two."""
        n, sim, end = self.cfg.physics_every, self.sim, self.cfg.duration_s
        if n > 1 and (sim.steps % n or (end is not None and end - sim.t_s < n * DT_S - 1e-9)):
            return 1
        return n

    def stop(self, *_: Any) -> None:
        """Ask the loop to end (signal handler)."""
        self.running = False

    def run(self) -> int:
        """Run until stopped or ``duration_s``; returns the exit status (0)."""
        for sig in (signal.SIGINT, signal.SIGTERM):
            signal.signal(sig, self.stop)
        cfg, sim = self.cfg, self.sim
        speed = cfg.speedup
        step_s = cfg.physics_every * DT_S
        wall0 = self.wall()
        sim0 = sim.t_s
        run_wall0, run_sim0 = wall0, sim0  # the pacing anchors move; the final line does not
        self._rtf = 0.0
        last_status_wall, last_status_sim = wall0, sim.t_s
        next_tick = wall0
        try:
            while self.running:
                now = self.wall()
                if self.gate is not None and sim0 + (now - wall0) * speed - sim.t_s > (
                    LOCKSTEP_SLACK_S
                ):  # lockstep: the speed-up is a ceiling; a wait is never caught up
                    wall0, sim0 = now, sim.t_s + LOCKSTEP_SLACK_S
                target = sim0 + (now - wall0) * speed
                batch_end = now + BATCH_WALL_S
                held = False
                while sim.t_s + step_s <= target + 1e-12:
                    if self.gate is not None and self._held():
                        held = True
                        break
                    sim.advance(self._steps_now())
                    self._after_step()
                    if cfg.duration_s is not None and sim.t_s >= cfg.duration_s - 1e-9:
                        self.running = False
                        break
                    if self.wall() > batch_end:
                        break
                now = self.wall()
                behind = (sim0 + (now - wall0) * speed) - sim.t_s
                self.lag_s = max(0.0, behind / speed - step_s / speed)
                timeout = 0.0 if behind >= step_s else min(0.05, (step_s - behind) / speed)
                if held:  # until an answer comes in, or the earliest wait's bound
                    deadline = self.gate.next_deadline_s(self._guided())
                    timeout = 0.0 if deadline is None else min(0.05, max(0.0, deadline - now))
                for key, _ in self.sel.select(timeout):
                    if key.data == "stdin":
                        self._stdin()
                    else:
                        self._receive(key.data)
                if self._new_speed is not None:  # re-anchor the pacing at the new rate
                    speed, self._new_speed = self._new_speed, None
                    wall0, sim0 = self.wall(), sim.t_s
                    cfg.speedup = speed
                if now >= next_tick:
                    next_tick = now + 0.1
                    self._forget_silent_peers(now)
                    for f in (self.truth, self.events):
                        if f:
                            f.flush()
                    for i, link in enumerate(self.links):
                        outs = link.tick(now)
                        if outs:
                            self._send(i, outs)
                            self._log_mission_events(i)
                        if self.signing:
                            self._log_rejects(i, now)
                if now - last_status_wall >= cfg.status_interval_s:
                    self._rtf = (sim.t_s - last_status_sim) / (now - last_status_wall)
                    last_status_wall, last_status_sim = now, sim.t_s
                    print(self.status_line(), file=self.err, flush=True)
        finally:
            if self.signing:
                for i in range(len(self.links)):
                    self._reject_logged[i] = (self._reject_logged[i][0], -1e9)
                    self._log_rejects(i, self.wall())
            elapsed = self.wall() - run_wall0
            if elapsed > 0:  # the final line reports the whole run
                self._rtf = (sim.t_s - run_sim0) / elapsed
            print(self.status_line(), file=self.err, flush=True)
            self.close()
        return 0

    def close(self) -> None:
        """Close sockets, flush logs and give stdin back its blocking mode (idempotent)."""
        if self._stdin_was_blocking is not None:
            with contextlib.suppress(OSError):
                os.set_blocking(0, self._stdin_was_blocking)
            self._stdin_was_blocking = None
        for s in self.socks:
            s.close()
        self.socks = []
        self.sel.close()
        for f in (getattr(self, "truth", None), getattr(self, "events", None)):
            if f:
                f.close()
        self.truth = self.events = None


def _frame_check(key: bytes | None) -> FrameCheck | None:
    """A vehicle's signing endpoint (wall-clock timestamps), None without a key."""
    if key is None:
        return None
    return FrameCheck(Signing(key, time.time, link_id=VEHICLE_LINK_ID))


def free_base_port(n: int, spacing: int = PORT_SPACING) -> int:
    """A base port such that ``base + spacing * i`` (i < n) are all free UDP ports now."""
    for _ in range(200):
        base = random.randrange(20000, 60000 - spacing * n)
        socks = []
        try:
            for i in range(n):
                s = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
                socks.append(s)
                s.bind(("127.0.0.1", base + spacing * i))
            return base
        except OSError:
            continue
        finally:
            for s in socks:
                s.close()
    raise RuntimeError("no free UDP port range found")
