"""The emulated Net F/T's RDT behaviour against ATI's documents, with hand-built requests.

Each test states the documented behaviour it checks; the sources are quoted in
docs/netft.md ("What the box does, with sources") and the fidelity table of
docs/emulators.md. Requests and records go through :mod:`netft_documented`
(struct layouts from the manual), never through forcelearn's codec.
"""

from __future__ import annotations

import itertools
from dataclasses import replace

from netft_documented import (
    INTERNAL_RATE_HZ,
    QUIET,
    QUIET_S,
    RECORD,
    RESET_LATCH,
    SET_BIAS,
    START_BUFFERED,
    START_REALTIME,
    STOP,
    RdtClient,
    records,
    request,
    start_box,
)


def test_a_start_request_for_n_samples_gets_n_records_numbered_1_to_n() -> None:
    """Records 1..N, one 36-byte record per datagram, status 0, then silence.

    Manual: "in a request for 1000 records, rdt_sequence will start at 1 and run to 1000".
    """
    with start_box() as box, RdtClient(box) as rdt:
        rdt.send(START_REALTIME, 10)
        got = [records(d) for d in rdt.datagrams(10)]
        assert all(len(r) == 1 for r in got)
        flat = [r[0] for r in got]
        assert [r[0] for r in flat] == list(range(1, 11))
        assert all(r[2] == 0 for r in flat)
        assert rdt.datagram(QUIET_S) is None  # then silence


def test_rdt_sequence_restarts_with_each_request_but_ft_sequence_does_not() -> None:
    """Manual: ft_sequence "does not reset to zero when an RDT request is received"."""
    with start_box() as box, RdtClient(box) as rdt:
        rdt.send(START_REALTIME, 5)
        first = [records(d)[0] for d in rdt.datagrams(5)]
        rdt.send(START_REALTIME, 5)
        second = [records(d)[0] for d in rdt.datagrams(5)]
    assert [r[0] for r in second] == [1, 2, 3, 4, 5]
    assert second[0][1] > first[-1][1]


def test_ft_sequence_counts_the_internal_7000_per_s_samples_whatever_the_rdt_rate() -> None:
    """At an RDT rate of 1000/s consecutive records are 7 internal samples apart.

    Manual: ft_sequence "increments at the internal sample rate (7000 per sec)".
    """
    with start_box(rdt_rate_hz=1000) as box, RdtClient(box) as rdt:
        rdt.send(START_REALTIME, 6)
        ft = [records(d)[0][1] for d in rdt.datagrams(6)]
    assert [b - a for a, b in itertools.pairwise(ft)] == [INTERNAL_RATE_HZ // 1000] * 5


def test_buffered_streaming_packs_rdt_buffer_size_records_per_datagram() -> None:
    """Command 0x0003 batches records per datagram by the RDT buffer size (comrdtbsiz).

    rdt_sequence still numbers every record 1..N, each one greater than the last.
    """
    with start_box(rdt_buffer_size=5) as box, RdtClient(box) as rdt:
        rdt.send(START_BUFFERED, 20)
        datagrams = rdt.datagrams(4)
        assert [len(d) for d in datagrams] == [5 * RECORD.size] * 4
        flat = [r for d in datagrams for r in records(d)]
        assert [r[0] for r in flat] == list(range(1, 21))
        ft = [r[1] for r in flat]
        assert ft == sorted(ft) and len(set(ft)) == 20  # twenty distinct samples, in order
        assert rdt.datagram(QUIET_S) is None


def test_buffered_streaming_with_sample_count_0_runs_until_stop() -> None:
    """Buffered, sample count 0: full-buffer datagrams until stop.

    Manual: with sample_count 0 the box "outputs continuously until a user sends a RDT
    request with command set to zero".
    """
    with start_box(rdt_rate_hz=1000, rdt_buffer_size=4) as box, RdtClient(box) as rdt:
        rdt.send(START_BUFFERED, 0)
        datagrams = rdt.datagrams(3)
        rdt.send(STOP)
        rdt.drain()
        assert rdt.datagram(QUIET_S) is None
    assert [len(d) for d in datagrams] == [4 * RECORD.size] * 3
    flat = [r[0] for d in datagrams for r in records(d)]
    assert flat == list(range(flat[0], flat[0] + 12))


def test_real_time_streaming_with_sample_count_0_runs_until_stop() -> None:
    """The same for 0x0002: one record per datagram until stop."""
    with start_box(rdt_rate_hz=1000) as box, RdtClient(box) as rdt:
        rdt.send(START_REALTIME, 0)
        datagrams = rdt.datagrams(5)
        rdt.send(STOP)
        rdt.drain()
        assert rdt.datagram(QUIET_S) is None
    assert [len(d) for d in datagrams] == [RECORD.size] * 5


def test_requests_of_the_wrong_header_size_or_command_get_no_answer() -> None:
    """Only 8-byte 0x1234 requests of a known command are answered.

    The box is not wedged by the others: a good request right after is answered.
    """
    with start_box() as box, RdtClient(box) as rdt:
        rdt.send_raw(bytes.fromhex("4321000200000001"))   # wrong header
        rdt.send_raw(request(START_REALTIME, 1)[:7])        # short
        rdt.send_raw(request(START_REALTIME, 1) + b"\x00")  # long
        rdt.send(0x0077, 1)                                 # no such command
        rdt.send(RESET_LATCH)                               # documented, answers nothing
        assert rdt.datagram(QUIET_S) is None
        rdt.send(START_REALTIME, 1)
        answer = rdt.datagram()
        assert answer is not None and records(answer)[0][0] == 1


def test_a_request_with_header_abcd_is_ignored_and_counted_by_reason() -> None:
    """0xABCD instead of 0x1234 is not a request the box recognises.

    Nothing comes back, even for a valid command and count behind the header, and
    the emulator counts each ignored request by its reason.
    """
    with start_box() as box, RdtClient(box) as rdt:
        rdt.send_raw(bytes.fromhex("ABCD000200000001"))  # start real-time, 1 record
        rdt.send_raw(bytes.fromhex("ABCD004200000000"))  # set software bias
        rdt.send_raw(request(START_REALTIME, 1)[:7])
        rdt.send(0x0077, 1)
        assert rdt.datagram(QUIET_S) is None
        assert box.stats.rejected_by_reason == {
            "REQUEST_HEADER": 2, "REQUEST_SIZE": 1, "COMMAND": 1
        }
        assert box.stats.rejected == 4 and box.stats.bias_commands == 0


def test_an_unknown_command_does_not_stop_a_stream() -> None:
    """Only stop (or a new start) ends a sample-count-0 stream."""
    with start_box(rdt_rate_hz=1000) as box, RdtClient(box) as rdt:
        rdt.send(START_REALTIME, 0)
        rdt.datagrams(2)
        rdt.send(0x0077)
        rdt.datagrams(50)  # still streaming well after the unknown command
        rdt.send(STOP)


def test_set_software_bias_zeroes_the_present_load_and_answers_nothing() -> None:
    """0x0042 answers nothing; later records read the load relative to the biased one.

    Here the load is static: zero counts on all six axes.
    """
    offsets = replace(QUIET, initial_bias=(0.8, -1.2, 2.0, 0.03, -0.05, 0.02))
    with start_box(contact_mm=8.0, model=offsets) as box, RdtClient(box) as rdt:
        rdt.send(START_REALTIME, 1)
        answer = rdt.datagram()
        assert answer is not None
        before = records(answer)[0][3:]
        rdt.send(SET_BIAS)
        assert rdt.datagram(QUIET_S) is None
        rdt.send(START_REALTIME, 1)
        answer = rdt.datagram()
        assert answer is not None
        after = records(answer)[0][3:]
    assert max(abs(c) for c in before) > 1_000_000  # more than 1 N of load and offset
    assert after == (0, 0, 0, 0, 0, 0)
