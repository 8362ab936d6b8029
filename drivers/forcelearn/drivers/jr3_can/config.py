"""Configuration of the JR3 CAN driver, one frozen dataclass validated at construction."""

from __future__ import annotations

from dataclasses import dataclass
from typing import Literal

from forcelearn.errors import ConfigError
from forcelearn.protocols.jr3_can.opcodes import OPCODE_MAPS, OpcodeMap
from forcelearn.protocols.jr3_can.scaling import INT16_MAX, check_full_scales, cutoff_to_wire


@dataclass(frozen=True)
class Jr3Config:
    """How the driver talks to one JR3-to-CAN adapter.

    Attributes:
        node_id: the adapter's node id (1..127).
        mode: ``"sync"`` (one sample per SYNC the host sends) or ``"async"``
            (the adapter streams every ``period_us``).
        cutoff_hz: the adapter's low-pass cut-off (0.01..655.35 Hz; 0: unfiltered, the
            raw decoupled data).
        period_us: async streaming period in microseconds.
        full_scales: six full scales (N, N, N, N*m, N*m, N*m); None reads them
            from the adapter at initialisation.
        zero_on_init: zero the offsets at each initialisation (tool in free space!). On by
            default, as the public host driver: the adapter's offsets are 0 after every
            power-up, reset and stop, so a host that does not zero reads the raw bias.
        zero_settle_s: wait before zeroing, so the adapter's filter settles.
        ack_timeout_s: how long to wait for each ACK.
        stale_timeout_s: no sample within this time raises ``SensorStale``.
        near_saturation_counts: |raw| at or above this flags the axis saturated.
        opcodes_version: key of the opcode map in ``OPCODE_MAPS``.
        log_path: optional traffic log; python-can picks the writer by suffix
            (``.blf``, ``.asc``, ``.log``, ``.csv``...).
    """

    node_id: int = 1
    mode: Literal["sync", "async"] = "sync"
    cutoff_hz: float = 125.0
    period_us: int = 1000
    full_scales: tuple[float, float, float, float, float, float] | None = None
    zero_on_init: bool = True
    zero_settle_s: float = 0.1
    ack_timeout_s: float = 0.25
    stale_timeout_s: float = 0.1
    near_saturation_counts: int = 26214
    opcodes_version: str = "2023-12"
    log_path: str | None = None

    def __post_init__(self) -> None:
        if not 1 <= self.node_id <= 127:
            raise ConfigError(f"jr3.node_id={self.node_id}: must be 1..127")
        if self.mode not in ("sync", "async"):
            raise ConfigError(f"jr3.mode={self.mode!r}: must be 'sync' or 'async'")
        try:
            cutoff_to_wire(self.cutoff_hz)
        except ValueError as exc:
            raise ConfigError(f"jr3.cutoff_hz: {exc}") from exc
        if not 1 <= self.period_us <= 0xFFFFFFFF:
            raise ConfigError(f"jr3.period_us={self.period_us}: must be a positive uint32")
        if self.full_scales is not None:
            try:
                check_full_scales(self.full_scales)
            except ValueError as exc:
                raise ConfigError(f"jr3.full_scales: {exc}") from exc
        for key in ("zero_settle_s", "ack_timeout_s", "stale_timeout_s"):
            if getattr(self, key) < 0 or (key != "zero_settle_s" and getattr(self, key) == 0):
                raise ConfigError(f"jr3.{key}={getattr(self, key)}: must be positive")
        if not 0 < self.near_saturation_counts <= INT16_MAX:
            raise ConfigError("jr3.near_saturation_counts: must be 1..32767")
        if self.opcodes_version not in OPCODE_MAPS:
            raise ConfigError(
                f"jr3.opcodes_version={self.opcodes_version!r}: known {sorted(OPCODE_MAPS)}"
            )

    @property
    def opcodes(self) -> OpcodeMap:
        """The opcode map this configuration speaks."""
        return OPCODE_MAPS[self.opcodes_version]
