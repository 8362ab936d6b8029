"""``can.Bus(interface="forcelearn-jr3", channel=NAME)``: a bus with an emulated JR3 on it.

python-can finds this class through the ``can.interface`` entry point
``forcelearn-jr3`` (pyproject.toml). The bus joins the in-process
:class:`~forcelearn.emulators.jr3.node.Jr3EmulatorNode` registered under
``channel`` (what the emulated cell starts: it shares the cell's physics). When
no node has that name at the bus's first send or receive, the bus starts one on
a cell of its own (the tool in free space at the default home pose, a default
sensor model; options below); later buses on the channel join it, as python-can's
``virtual`` channels are joined by name, and it stops with the last of them. So
the bus may open before the node, as on a real bus.

Frames cost no thread hand-over: :meth:`Jr3EmulatorBus.send` hands the frame
to the node; when ``recv`` finds nothing to return, the host is waiting, so the
node runs its next loop turn (:meth:`Jr3EmulatorNode.serve_pending`) and its
answers are returned. In async mode the node streams on the host's wall clock, emitted by
whichever thread waits in ``recv`` (the driver's ``can.Notifier``).
"""

from __future__ import annotations

import collections
import threading
import time
import weakref
from collections.abc import Callable
from dataclasses import fields
from typing import Any

import can
from can.typechecking import AutoDetectedConfig

from forcelearn.emulators import registry
from forcelearn.emulators.jr3.firmware import CarriedSample
from forcelearn.emulators.jr3.node import REGISTRY_KIND, Jr3EmulatorNode
from forcelearn.emulators.jr3.sensor_model import Jr3ModelParams

INTERFACE = "forcelearn-jr3"
_MODEL_OPTIONS = {f.name for f in fields(Jr3ModelParams)}
_new_node_lock = threading.Lock()
_started_by_a_bus: weakref.WeakSet[Jr3EmulatorNode] = weakref.WeakSet()
"""Nodes a bus started (they stop with their last bus); the cell's own nodes are not here."""


class Jr3EmulatorBus(can.BusABC):
    """A python-can bus on which an emulated JR3 adapter answers.

    Args:
        channel: name of the in-process node to join (or to start).
        node_id: node id of a node this bus starts (1..127).
        seed: noise seed of a node this bus starts.
        bitrate: bit/s of the bus, for the frames' simulated time (a node this
            bus starts; default 1 Mbit/s).
        receive_own_messages: also receive the frames this bus sends.
        **kwargs: sensor-model fields (``noise_std``, ``full_scales``,
            ``initial_bias``...: :class:`Jr3ModelParams`) for a node this
            bus starts; python-can's generic options are accepted and ignored.
    """

    def __init__(
        self,
        channel: Any = None,
        *,
        node_id: int = 1,
        seed: int | None = 0,
        bitrate: float | None = None,
        receive_own_messages: bool = False,
        **kwargs: Any,
    ) -> None:
        if channel is None or not str(channel):
            raise can.CanInitializationError(
                f"{INTERFACE}: name a channel, e.g. can.Bus(interface={INTERFACE!r}, "
                "channel='jr3')"
            )
        self.channel = str(channel)
        self.channel_info = f"forcelearn JR3 emulator on {self.channel!r}"
        self.receive_own_messages = receive_own_messages
        self._rx: collections.deque[can.Message] = collections.deque()
        self._rx_lock = threading.RLock()
        self._cond = threading.Condition(self._rx_lock)
        """Waits and notifies on ``_cond``; ``with self._rx_lock`` holds it (one C call, where
        the condition's own ``with`` adds a Python frame each way: every frame passes here)."""
        self._closed = False
        model = {k: kwargs.pop(k) for k in list(kwargs) if k in _MODEL_OPTIONS}
        try:
            options: dict[str, Any] = {
                k: tuple(v) if isinstance(v, list) else v for k, v in model.items()
            }
            params = Jr3ModelParams(**options)
        except (TypeError, ValueError) as exc:
            raise can.CanInitializationError(f"{INTERFACE} on {self.channel!r}: {exc}") from exc
        if not 1 <= node_id <= 127:
            raise can.CanInitializationError(f"{INTERFACE}: node_id={node_id} is not 1..127")
        self._private = (node_id, seed, 1_000_000 if bitrate is None else bitrate, params)
        self._node: Jr3EmulatorNode | None = None
        super().__init__(channel=self.channel, **kwargs)

    @property
    def node(self) -> Jr3EmulatorNode:
        """The node on this bus, joined at first use (so the bus may open before the node)."""
        if self._node is None:
            with _new_node_lock:
                node = registry.lookup(REGISTRY_KIND, self.channel)
                if node is None:
                    node = _private_node(self.channel, *self._private)
                node.attach_host(self._deliver)
                self._node = node
        return self._node

    def _deliver(self, msg: can.Message) -> None:
        with self._rx_lock:
            self._rx.append(msg)
            self._cond.notify_all()

    def send(self, msg: can.Message, timeout: float | None = None) -> None:
        """Put ``msg`` on the bus: the node answers before this returns."""
        if self._closed:
            raise can.CanOperationError(f"{INTERFACE} bus on {self.channel!r} is shut down")
        node = self._running_node()
        if self.receive_own_messages:  # the host's copy of its own frame, as received
            self._deliver(can.Message(
                timestamp=time.time(), arbitration_id=msg.arbitration_id,
                is_extended_id=msg.is_extended_id, is_remote_frame=msg.is_remote_frame,
                is_error_frame=msg.is_error_frame, dlc=msg.dlc, data=bytes(msg.data),
                channel=self.channel, is_rx=True,
            ))
        node.receive(msg)  # handled before this returns: the node keeps nothing of it

    carries = True
    """Carry a SYNC and its answer unframed when the driver asks (:meth:`carry_sync`); False:
    frames only (a test compares the two)."""

    def carry_sync(self, node_id: int) -> CarriedSample | None:
        """Send a SYNC and take node ``node_id``'s answer now: its six counts and counter.

        What :meth:`send` of the SYNC frame and :meth:`recv` of the answer's frames
        give (``Jr3EmulatorNode.carry_sync``), with no frame encoded or decoded;
        None (nothing sent) when the frames must go: frames already wait, this bus
        receives its own frames, or the node cannot carry.
        """
        if self._closed:
            raise can.CanOperationError(f"{INTERFACE} bus on {self.channel!r} is shut down")
        if not self.carries or self.receive_own_messages or self._rx:
            return None
        return self._running_node().carry_sync(node_id)

    def carry_syncs(self, node_id: int, count: int,
                    take: Callable[[tuple[int, int, int, int, int, int], int], bool]) -> int | None:
        """:meth:`carry_sync` up to ``count`` times, each answer handed to ``take`` at once.

        ``Jr3EmulatorNode.carry_syncs``: stops after an answer ``take`` refuses; the SYNCs
        carried, or None (nothing sent) when :meth:`carry_sync` would answer None.
        """
        if self._closed:
            raise can.CanOperationError(f"{INTERFACE} bus on {self.channel!r} is shut down")
        if not self.carries or self.receive_own_messages or self._rx:
            return None
        return self._running_node().carry_syncs(node_id, count, take)

    def _recv_internal(self, timeout: float | None) -> tuple[can.Message | None, bool]:
        deadline = None if timeout is None else time.monotonic() + timeout
        node = self.node
        while True:
            until_sample = node.emit_due()
            # a deque's truth is one atomic read: frames already in need no turn of the loop
            if not self._rx and node.serve_pending():  # the host waits: the loop turns
                continue
            with self._rx_lock:
                if self._rx:
                    return self._rx.popleft(), False
                if self._closed:
                    raise can.CanOperationError(f"{INTERFACE} bus on {self.channel!r} is shut down")
                left = None if deadline is None else deadline - time.monotonic()
                if left is not None and left <= 0:
                    return None, False
                waits = [w for w in (left, until_sample) if w is not None]
                self._cond.wait(min(waits) if waits else None)

    def _running_node(self) -> Jr3EmulatorNode:
        """The bus's node; CanOperationError once it has stopped."""
        node = self.node
        if node.closed:  # a node unregisters its channel when it closes, never before
            raise can.CanOperationError(
                f"the JR3 emulator on {self.channel!r} has stopped: open the bus again"
            )
        return node

    def shutdown(self) -> None:
        """Leave the bus (a node this bus started stops with its last bus); idempotent."""
        if self._closed:
            return
        with self._rx_lock:
            self._closed = True
            self._cond.notify_all()
        node, self._node = self._node, None
        if node is not None:
            node.detach_host(self._deliver)
            with _new_node_lock:
                if node.hosts == 0 and node in _started_by_a_bus:
                    node.close()
        super().shutdown()

    @staticmethod
    def _detect_available_configs() -> list[AutoDetectedConfig]:
        return [AutoDetectedConfig(interface=INTERFACE, channel=name)
                for name in registry.names(REGISTRY_KIND)]


def _private_node(
    channel: str, node_id: int, seed: int | None, bitrate: float, params: Jr3ModelParams
) -> Jr3EmulatorNode:
    """A node on a cell of its own (free space, home pose), started for a bus."""
    from forcelearn.emulators.physics.arm import HOME
    from forcelearn.emulators.physics.cell import CellPhysics

    node = Jr3EmulatorNode(
        CellPhysics(pose=HOME), channel=channel, node_id=node_id, model=params, seed=seed,
        bitrate=bitrate, in_process=True,
    )
    _started_by_a_bus.add(node)
    return node
