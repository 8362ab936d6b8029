"""Helpers of the Net F/T emulator tests: physics, a quiet model, an emulator, a driver config."""

from __future__ import annotations

from dataclasses import replace
from typing import Any

from forcelearn.devices import Pose
from forcelearn.drivers.netft import NetFtConfig
from forcelearn.emulators.clock import SimClock
from forcelearn.emulators.netft import NetFtEmulator, NetFtModelParams
from forcelearn.emulators.physics.cell import CellPhysics
from forcelearn.emulators.physics.sponge import Sponge
from forcelearn.emulators.physics.tool import ToolParams

QUIET = NetFtModelParams(noise_std=(0.0,) * 6, initial_bias=(0.0,) * 6,
                         bias_drift_per_sqrt_s=(0.0,) * 6)
"""A noise-free, bias-free transducer: readings are the physics, quantised."""


def contact_physics(depth_mm: float = 8.0) -> CellPhysics:
    """The tool pressed ``depth_mm`` into the sponge (a few N along +Fy)."""
    return CellPhysics(Sponge(), Pose(0.0, -depth_mm, -40.0), tool=ToolParams())


def config_for(emulator: NetFtEmulator, **overrides: Any) -> NetFtConfig:
    """A driver config for ``emulator`` (stale timeout generous for a loaded CI host)."""
    base = NetFtConfig(host=emulator.host, stale_timeout_s=0.5, **emulator.ports)
    return replace(base, **overrides)


def start(physics: CellPhysics | None = None, **options: Any) -> NetFtEmulator:
    """An emulator on free ports (tests never take the box's fixed ports)."""
    options.setdefault("rdt_port", 0)
    options.setdefault("tcp_port", 0)
    return NetFtEmulator(physics or contact_physics(), options.pop("clock", SimClock()),
                         **options)
