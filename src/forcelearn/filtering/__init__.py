"""Filters of the sensed contact force (hardware-agnostic; fed by any ForceSensor)."""

from forcelearn.filtering.kalman import ForceFilter, ForceFilterConfig

__all__ = ["ForceFilter", "ForceFilterConfig"]
