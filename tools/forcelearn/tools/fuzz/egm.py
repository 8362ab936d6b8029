"""Fuzz target ``egm``: hostile datagrams to the real EGM driver over real loopback UDP.

A scripted controller (a UDP socket on 127.0.0.1) opens a session with an
:class:`~forcelearn.drivers.egm.EgmRobot` in real mode (its receive
thread answers at once) and then runs one cycle per input, its feedback the
planned pose it was last sent. Before each cycle an input is played: datagrams
from the controller's own address (as a host forging it would) or from two
other hosts, and sometimes a call of the driver's public API.

==================  ===========================================================
input               what is sent
==================  ===========================================================
mutant              the controller's next datagram with 1 to 4 byte mutations
truncation          its first 0..n-1 bytes
huge / tiny         65,507, 9,000 or 1,000 random bytes; 0 to 8 random bytes
foreign             a well-formed next-seqno datagram from another host
session start       seqno 0 with an evil pose (2500 mm, NaN, inf, 1e308, a
                    zero or 3-element-like quaternion) and a random tm
replay              one of the controller's earlier datagrams (session starts too)
seqno jump          the next datagram with seqno + 2, + bound, + bound + 1,
                    + 2^31 - 2, + 2^31, - 1, or random
version mix         the next datagram in the other RobotWare's egm.proto
evil feedback       the next datagram from the controller, its pose evil
restart             the controller restarts for real (seqno 0, newer tm)
move_to / stop      a target (valid, NaN, huge, outside, 3 or 5 elements,
                    non-unit, text) or a hold, through the public API
==================  ===========================================================

Properties, each input (a failure names which):

1. no exception but forcelearn's typed errors from the API calls;
2. one of the controller's next :data:`ATTEMPTS` cycles is answered: no
   input ends the session (a forged datagram may hold the stream back a few
   cycles, until the controller catches up or the driver takes its stream up
   again; counted as "delayed");
3. nothing is ever sent to another host;
4. every planned pose on the wire is finite, unit, inside the client
   workspace and within one ramp step (speed x period, 45 deg/s) of the
   previous one, per reply;
5. no hang: each input ends within a few seconds.

Blocks of :data:`BLOCK` inputs alternate RW7 and RW6 drivers, with and
without ``controller_host``/``controller_port`` configured.
"""

from __future__ import annotations

import math
import random
import socket
import time
from collections import Counter
from collections.abc import Callable
from dataclasses import dataclass, field

import numpy as np

from forcelearn.devices import Pose
from forcelearn.drivers.egm import EgmConfig, EgmRobot
from forcelearn.drivers.egm.guidance import TURN_DEG_S, angle_deg
from forcelearn.errors import ForcelearnError
from forcelearn.protocols.egm import codec

Mutate = Callable[[bytes, random.Random], bytes]
"""Byte mutations of a datagram (``forcelearn.tools.fuzz.targets`` passes its own)."""


class FuzzFailure(AssertionError):
    """A property of the target failed; the message says which.

    Its own class, not ``forcelearn.tools.fuzz.targets.FuzzFailure``: this module does
    not import the harness (which imports it), so no import cycle.
    """

BLOCK = 2000
"""Inputs per driver; then a new driver, version and pairing mode."""
HOME = Pose(900.0, 0.0, 600.0, (0.0, 1.0, 0.0, 0.0))
REPLY_TIMEOUT_S = 2.0
"""Longest wait for the answer to the controller's cycle before the session counts as ended."""
ATTEMPTS = 6
"""Cycles the controller runs after an input before the session counts as ended (24 ms)."""
POLL_S = 0.02
"""Slice of the wait for an answer: how soon an unanswered cycle is known once taken."""
HANG_S = 10.0
"""An input that takes longer than this counts as a hang."""
EPS_MM = 1e-9
EPS_DEG = 1e-6

EVIL_POSES = (
    Pose(2500.0, 0.0, 600.0, HOME.quaternion),
    Pose(math.nan, 0.0, 600.0, HOME.quaternion),
    Pose(900.0, math.inf, 600.0, HOME.quaternion),
    Pose(900.0, 0.0, -math.inf, HOME.quaternion),
    Pose(1e308, -1e308, 1e308, HOME.quaternion),
    Pose(5e-324, 0.0, 600.0, HOME.quaternion),
    Pose(900.0, 0.0, 600.0, (0.0, 0.0, 0.0, 0.0)),
    Pose(900.0, 0.0, 600.0, (math.nan, 1.0, 0.0, 0.0)),
    Pose(900.0, 0.0, 600.0, (1.0, 1.0, 0.0, 0.0)),
    Pose(300.0, -800.0, -200.0, HOME.quaternion),
    Pose(1500.0, 800.0, 1400.0, HOME.quaternion),
)
"""Poses a hostile datagram may carry (the last two: the workspace's corners, allowed)."""


def _robot(seqno: int, tm_ms: int, pose: Pose, version: codec.Version) -> bytes:
    """A controller's EgmRobot with version evidence (a measured force), guidance running."""
    return codec.encode_robot(codec.RobotMessage(
        seqno=seqno % 2**32, tm_ms=tm_ms % 2**32, feedback=pose, planned=pose,
        time_us=tm_ms * 1000, motor=codec.MotorState.ON, mci=codec.MciState.RUNNING,
        rapid=codec.RapidState.RUNNING, measured_force=(0.0,) * 6,
        fc_active=False if version == "rw7" else None,
    ), version)


def _udp() -> socket.socket:
    sock = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
    sock.bind(("127.0.0.1", 0))
    return sock


@dataclass
class EgmInput:
    """One input: datagrams (sender 0 = the controller's address, 1-2 other hosts), a call."""

    datagrams: list[tuple[int, bytes]] = field(default_factory=list)
    call: Callable[[EgmRobot], object] | None = None
    restart: bool = False
    what: str = ""


@dataclass
class EgmRig:
    """A real-mode driver, its scripted controller and two other hosts, over loopback UDP."""

    driver: EgmRobot
    controller: socket.socket
    others: list[socket.socket]
    version: codec.Version
    seqno: int = 0
    tm_ms: int = 0
    pose: Pose = HOME
    planned: Pose | None = None
    reply_seqno: int | None = None
    history: list[bytes] = field(default_factory=list)
    starts: list[bytes] = field(default_factory=list)
    delayed: int = 0
    sent: int = 0

    @classmethod
    def open(cls, version: codec.Version, pinned: bool) -> EgmRig:
        """Bind a driver and open its session from a fresh controller socket."""
        controller = _udp()
        config = EgmConfig(
            port=0, lockstep=False, version=version, watchdog_s=1.0, stale_after_s=60.0,
            controller_host="127.0.0.1" if pinned else None,
            controller_port=controller.getsockname()[1] if pinned else None,
        )
        driver = EgmRobot(config)
        rig = cls(driver, controller, [_udp(), _udp()], version, seqno=-1, tm_ms=1000)
        rig.cycle()
        driver.wait_for_session(REPLY_TIMEOUT_S)
        return rig

    def close(self) -> None:
        """Close the driver and the sockets."""
        self.driver.close()
        for sock in (self.controller, *self.others):
            sock.close()

    @property
    def bound(self) -> int:
        """The driver's largest plausible seqno jump."""
        return self.driver.config.max_seqno_ahead

    def next_datagram(self, seqno_delta: int = 1, pose: Pose | None = None,
                      version: codec.Version | None = None) -> bytes:
        """The controller's next datagram (not sent; seqno and tm not advanced)."""
        return _robot(self.seqno + seqno_delta, self.tm_ms + 4, pose or self.pose,
                      version or self.version)

    def send(self, sender: int, data: bytes) -> None:
        """Send ``data`` to the driver from the controller (0) or another host (1, 2)."""
        sock = self.controller if sender == 0 else self.others[sender - 1]
        try:
            sock.sendto(data, ("127.0.0.1", self.driver.port))
        except OSError as exc:  # e.g. EMSGSIZE: nothing left the socket
            if len(data) < 65000:
                raise FuzzFailure(f"loopback send of {len(data)} bytes raised {exc!r}") from exc
            return
        self.sent += 1

    def cycle(self, restart: bool = False) -> str:
        """Run the controller's next cycle; check every answer; "answered" or "delayed"."""
        self.seqno = -1 if restart else self.seqno
        for attempt in range(ATTEMPTS):
            self.seqno = (self.seqno + 1) % 2**32
            self.tm_ms += 4
            data = _robot(self.seqno, self.tm_ms, self.pose, self.version)
            self.history = [*self.history[-63:], data]
            if self.seqno == 0:
                self.starts.append(data)
            self.send(0, data)
            self._await(self.tm_ms)
            latest = self.driver.read_status().seqno
            if latest == self.seqno:  # the driver took this cycle (not a forgery's with our tm)
                return "answered" if attempt == 0 else "delayed"
            self.delayed += 1
            if 0 <= (latest - self.seqno) % 2**32 <= self.bound:
                self.seqno = latest  # a forged seqno within the bound took ours: catch up
            # else the controller just goes on with its next cycle, as a real one does
        raise FuzzFailure(f"an input ended the session: {ATTEMPTS} cycles up to {self.seqno} "
                          f"got no answer ({self.driver.stats})")

    def _await(self, tm_ms: int) -> None:
        """Read and check answers until the driver has taken all sent and none more comes.

        Stops early at the answer to ``tm_ms`` once every datagram sent was
        taken; gives up after :data:`REPLY_TIMEOUT_S`.
        """
        deadline = time.monotonic() + REPLY_TIMEOUT_S
        answered = False
        while time.monotonic() < deadline:
            taken = self.driver.stats.received >= self.sent
            if answered and taken:
                return
            self.controller.settimeout(POLL_S)
            try:
                raw, _ = self.controller.recvfrom(65535)
            except TimeoutError:
                if taken:
                    return
                continue
            reply = codec.decode_sensor(raw, self.version)
            self._check_reply(reply)
            answered = answered or reply.tm_ms == tm_ms % 2**32

    def _check_reply(self, reply: codec.SensorMessage) -> None:
        planned = reply.planned
        if planned is None:
            raise FuzzFailure(f"an EgmSensor without a planned pose: {reply}")
        values = (planned.x_mm, planned.y_mm, planned.z_mm, *planned.quaternion)
        limits = self.driver.config.limits
        inside = all(limits.workspace_min_mm[i] <= values[i] <= limits.workspace_max_mm[i]
                     for i in range(3))
        norm = math.sqrt(sum(q * q for q in planned.quaternion))
        if not (all(math.isfinite(v) for v in values) and inside and abs(norm - 1) < 1e-3):
            raise FuzzFailure(f"sent a planned pose outside the workspace or not finite: {planned}")
        if self.planned is not None:
            gap = 1
            if self.reply_seqno is not None and reply.seqno != 0:
                gap = max(1, (reply.seqno - self.reply_seqno) % 2**32)
            period = self.driver.config.sample_period_s
            step = float(np.linalg.norm(planned.position_mm - self.planned.position_mm))
            turn = angle_deg(planned.quaternion, self.planned.quaternion)
            if (step > gap * self.driver.config.speed_mm_s * period + EPS_MM
                    or turn > gap * TURN_DEG_S * period + EPS_DEG):
                raise FuzzFailure(f"sent a jump of {step:.6f} mm / {turn:.6f} deg in "
                                  f"{gap} reply(ies): {self.planned} -> {planned}")
        self.planned, self.reply_seqno, self.pose = planned, reply.seqno, planned

    def drain_others(self) -> None:
        """Fail if another host received anything."""
        for sock in self.others:
            sock.setblocking(False)
            try:
                data = sock.recv(65535)
            except BlockingIOError:
                continue
            finally:
                sock.setblocking(True)
            raise FuzzFailure(f"answered a host that is not the controller ({len(data)} bytes)")


def _target(rng: random.Random, rig: EgmRig) -> object:
    """A target for move_to: near the present one, or malformed in one of many ways."""
    base = rig.driver.target or HOME
    roll = rng.random()
    if roll < 0.5:
        d = [rng.uniform(-3.0, 3.0) for _ in range(3)]
        return base.moved(*d)
    bad: list[object] = [
        Pose(math.nan, base.y_mm, base.z_mm, base.quaternion),
        Pose(base.x_mm, math.inf, base.z_mm, base.quaternion),
        Pose(1e308, base.y_mm, base.z_mm, base.quaternion),
        Pose(2500.0, base.y_mm, base.z_mm, base.quaternion),
        Pose(base.x_mm, base.y_mm, base.z_mm, (0.0, 1.0, 0.0)),  # type: ignore[arg-type]
        Pose(base.x_mm, base.y_mm, base.z_mm, (0.0, 1.0, 0.0, 0.0, 0.0)),  # type: ignore[arg-type]
        Pose(base.x_mm, base.y_mm, base.z_mm, (1.0, 1.0, 0.0, 0.0)),
        Pose(base.x_mm, base.y_mm, base.z_mm, (math.nan, 1.0, 0.0, 0.0)),
        Pose("900", base.y_mm, base.z_mm, base.quaternion),  # type: ignore[arg-type]
        Pose(base.x_mm, base.y_mm, base.z_mm, "wxyz"),  # type: ignore[arg-type]
        base.moved(dz_mm=-50.0),
        None,
        "home",
    ]
    return rng.choice(bad)


def random_egm_input(rng: random.Random, rig: EgmRig, mutate: Mutate) -> EgmInput:
    """Draw one hostile input for ``rig``'s present state."""
    attack = rng.choices(
        ["mutant", "truncation", "huge", "tiny", "foreign", "start", "replay", "jump",
         "version", "evil", "restart", "move", "stop"],
        weights=(20, 6, 2, 4, 6, 8, 8, 8, 5, 6, 3, 12, 2),
    )[0]
    sender = 0 if rng.random() < 0.6 else rng.choice((1, 2))
    item = EgmInput(what=attack)
    if attack == "mutant":
        item.datagrams.append((sender, mutate(rig.next_datagram(), rng)))
    elif attack == "truncation":
        good = rig.next_datagram()
        item.datagrams.append((sender, good[: rng.randrange(len(good))]))
    elif attack == "huge":
        item.datagrams.append((sender, rng.randbytes(rng.choice((65507, 9000, 1000)))))
    elif attack == "tiny":
        item.datagrams.append((sender, rng.choice((b"\x0b", rng.randbytes(rng.randrange(9))))))
    elif attack == "foreign":
        for _ in range(rng.randint(1, 3)):
            pose = rng.choice(EVIL_POSES) if rng.random() < 0.5 else rig.pose.moved(5.0)
            item.datagrams.append((rng.choice((1, 2)), rig.next_datagram(1, pose)))
    elif attack == "start":
        item.datagrams.append((sender, _robot(0, rng.randrange(2**32), rng.choice(EVIL_POSES),
                                              rig.version)))
    elif attack == "replay":
        pool = rig.starts if rng.random() < 0.5 else rig.history
        item.datagrams.append((sender, rng.choice(pool)))
    elif attack == "jump":
        delta = rng.choice((2, rig.bound, rig.bound + 1, 2**31 - 2, 2**31, -1,
                            rng.randrange(2**32)))
        item.datagrams.append((sender, rig.next_datagram(delta)))
    elif attack == "version":
        other: codec.Version = "rw6" if rig.version == "rw7" else "rw7"
        item.datagrams.append((sender, rig.next_datagram(1, version=other)))
    elif attack == "evil":
        item.datagrams.append((sender, rig.next_datagram(1, rng.choice(EVIL_POSES))))
    elif attack == "restart":
        item.restart = True
    elif attack == "move":
        target = _target(rng, rig)
        item.call = lambda driver: driver.move_to(target)  # type: ignore[arg-type]
    else:
        item.call = lambda driver: driver.stop()
    return item


def check_egm(rig: EgmRig, item: EgmInput) -> str:
    """Play ``item`` against ``rig``; "answered" or "delayed", else a FuzzFailure."""
    started = time.monotonic()
    for sender, data in item.datagrams:
        rig.send(sender, data)
    if item.call is not None:
        try:
            item.call(rig.driver)
        except ForcelearnError:
            pass
        except Exception as exc:
            raise FuzzFailure(f"{item.what}: the driver raised {type(exc).__name__}: "
                              f"{exc}") from exc
    outcome = rig.cycle(restart=item.restart)
    rig.drain_others()
    try:
        rig.driver.read_pose()
    except ForcelearnError as exc:
        raise FuzzFailure(f"{item.what}: the session ended: {exc}") from exc
    if time.monotonic() - started > HANG_S:
        raise FuzzFailure(f"{item.what}: a hang of {time.monotonic() - started:.1f} s")
    return outcome


@dataclass
class EgmTally:
    """Outcome of a run: counts by outcome, the first failures, the drivers' summed counters."""

    outcomes: Counter[str] = field(default_factory=Counter)
    failures: list[str] = field(default_factory=list)
    counters: Counter[str] = field(default_factory=Counter)

    def add(self, rig: EgmRig, item: EgmInput) -> None:
        """Play one input; a failure is "foreign exception" if something raised, else "unsafe"."""
        try:
            self.outcomes[check_egm(rig, item)] += 1
        except FuzzFailure as exc:
            self.outcomes["foreign exception" if "raised" in str(exc) else "unsafe"] += 1
            if len(self.failures) < 10:
                self.failures.append(f"{item.what}: {exc}")


def run_target(inputs: int, rng: random.Random, mutate: Mutate) -> EgmTally:
    """Run ``inputs`` inputs in blocks of :data:`BLOCK`, a new driver per block."""
    tally = EgmTally()
    done = 0
    block = 0
    while done < inputs:
        version: codec.Version = ("rw7", "rw6")[block % 2]
        rig = EgmRig.open(version, pinned=block % 4 >= 2)
        try:
            for _ in range(min(BLOCK, inputs - done)):
                tally.add(rig, random_egm_input(rng, rig, mutate))
                done += 1
        finally:
            tally.counters.update(vars(rig.driver.stats))
            rig.close()
        block += 1
    return tally
