"""What the wire protocols themselves cost on this machine: their byte and frame exchanges, bare.

The machine floors (:mod:`.floors`) time one echo through a pty and one
round trip on the virtual CAN bus. A computer-link move and a JR3 sync read
are not quite those: each is a fixed sequence of writes and reads, fixed by
the protocol. These floors run exactly that sequence, through the same
endpoints and threads as the real driver and emulator, with no protocol
work at all (the bytes are made once, before the clock starts; nothing is
parsed, checked or computed), so a figure over its protocol floor is the
cost of the Python that both ends run per exchange.

=================  ===========================================================
protocol floor     the sequence timed (p50 or rate), as the driver and emulator do it
=================  ===========================================================
link move          PC: write the 22-byte MOVE_BY request frame (pyserial), read
exchange           the controller's answer, write its 2-byte DLE ACK. Controller
                   (a thread on the emulators' ``PtyEndpoint``): read until the
                   request is whole (the previous move's ACK comes in the same
                   read), write its DLE ACK and the reply frame in one write
                   (13 bytes). One round trip and one more write: the frames
                   are those of :mod:`forcelearn.protocols.computer_link`.
JR3 sync read      host: send SYNC on a python-can ``virtual`` bus and receive
exchange           the two frames that answer it, in the calling thread as the
                   sync driver does; adapter (a thread on a second bus of the
                   channel): receive the SYNC, send the force and the moment
                   frames (:mod:`forcelearn.protocols.jr3_can`'s). Three
                   frames where the CAN round trip floor has two.
=================  ===========================================================
"""

from __future__ import annotations

import statistics
import threading
import time
import uuid

import can
import numpy as np
import serial

from forcelearn.emulators.pty_endpoint import PtyEndpoint
from forcelearn.protocols.computer_link import framing
from forcelearn.protocols.computer_link import messages as m
from forcelearn.protocols.jr3_can import codec


def link_move_frames() -> tuple[bytes, bytes, bytes]:
    """A MOVE_BY's three writes: the request frame, the ACK and reply, the PC's ACK (bytes)."""
    ack = framing.Control.ACK.wire
    request = framing.encode(m.encode_request(m.Command.MOVE_BY, 1, m.increment_body(
        (0.0, 0.0, 0.05))))
    reply = framing.encode(m.encode_reply(m.Reply(m.Command.MOVE_BY, 1, m.ErrorCode.OK)))
    return request, ack + reply, ack


def link_move_exchange_s(rounds: int = 2000) -> float:
    """Return the p50 (s) of a computer-link move's byte exchange through a pty, bare."""
    request, answer, ack = link_move_frames()
    endpoint = PtyEndpoint("protocol-floor")
    stop = threading.Event()

    def controller() -> None:
        received, answered = 0, 0
        while not stop.is_set():
            data = endpoint.read(0.05)
            received += len(data)
            # request k (from 0) is whole once k requests and k ACKs came before it
            while received >= answered * (len(request) + len(ack)) + len(request):
                endpoint.write(answer)
                answered += 1

    thread = threading.Thread(target=controller, name="link-floor", daemon=True)
    thread.start()
    times = np.empty(rounds)
    try:
        with serial.Serial(endpoint.address, timeout=1.0) as port:
            for i in range(rounds + 100):
                start = time.perf_counter()
                port.write(request)
                if len(port.read(len(answer))) != len(answer):
                    raise RuntimeError("the pty controller thread did not answer within 1 s")
                port.write(ack)
                if i >= 100:
                    times[i - 100] = time.perf_counter() - start
    finally:
        stop.set()
        thread.join(1.0)
        endpoint.close()
    return float(np.percentile(times, 50))


def jr3_sync_exchanges_per_s(rounds: int = 3000, repeats: int = 3) -> float:
    """Return JR3 sync exchanges per second (SYNC out, two frames back) on a virtual bus."""
    sync = codec.encode(codec.Sync(), 0)
    forces = codec.encode(codec.Forces((100, -200, 300), 1), 1)
    moments = codec.encode(codec.Moments((10, -20, 30), 1), 1)
    answer = [can.Message(arbitration_id=f.arbitration_id, data=f.data, is_extended_id=False)
              for f in (forces, moments)]
    rates = []
    for _ in range(repeats):
        channel = f"protocol-floor-{uuid.uuid4().hex[:8]}"
        with can.Bus(interface="virtual", channel=channel) as host, \
                can.Bus(interface="virtual", channel=channel) as adapter:
            stop = threading.Event()

            def serve(bus: can.BusABC = adapter, done: threading.Event = stop) -> None:
                while not done.is_set():
                    if bus.recv(0.05) is not None:
                        for frame in answer:
                            bus.send(frame)

            thread = threading.Thread(target=serve, name="jr3-floor", daemon=True)
            thread.start()
            msg = can.Message(arbitration_id=sync.arbitration_id, data=sync.data,
                              is_extended_id=False)
            try:
                for i in range(100 + rounds):
                    if i == 100:
                        start = time.perf_counter()
                    host.send(msg)
                    if host.recv(1.0) is None or host.recv(1.0) is None:
                        raise RuntimeError("the CAN adapter thread did not answer within 1 s")
                rates.append(rounds / (time.perf_counter() - start))
            finally:
                stop.set()
                thread.join(1.0)
    return float(statistics.median(rates))
