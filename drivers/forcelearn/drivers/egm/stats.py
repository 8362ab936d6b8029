"""The EGM driver's traffic counters: every datagram received is used or counted here."""

from __future__ import annotations

from dataclasses import dataclass


@dataclass(frozen=True)
class EgmStats:
    """Counters of one driver's traffic since it opened."""

    received: int = 0
    """EgmRobot datagrams received (fresh or not)."""
    replies: int = 0
    """EgmSensor datagrams sent."""
    missed: int = 0
    """Controller seqnos skipped (lost, or still to arrive out of order)."""
    duplicates: int = 0
    out_of_order: int = 0
    """Datagrams older than the latest one; ignored."""
    sessions: int = 0
    """Sessions seen (1 after opening; +1 per controller restart)."""
    bad_datagrams: int = 0
    """Datagrams that were not a readable EgmRobot with a finite feedback pose; ignored."""
    foreign_datagrams: int = 0
    """Datagrams from another source than the paired controller; never answered nor read."""
    wrong_version: int = 0
    """Datagrams proving the other RobotWare egm.proto than robot.version; ignored."""
    seqno_jumps: int = 0
    """Datagrams whose seqno jumps ahead by more than max_seqno_ahead; ignored."""
    replays: int = 0
    """Datagrams older (header tm) than the latest: a seqno 0 not newer, or a newer seqno
    with an older tm (an earlier session's datagram); ignored."""
    refused_sessions: int = 0
    """Session starts refused: feedback not finite, not unit or outside the workspace."""
    resumed_streams: int = 0
    """Seqno 0s undone: the stream they interrupted went on (a forged restart); answered."""
    resyncs: int = 0
    """Times the stream was taken up again after a forged datagram held it back."""
    unsent_replies: int = 0
    """Replies withheld because the planned pose failed its check (never expected)."""
