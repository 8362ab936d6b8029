"""Filters of the sensed contact force (hardware-agnostic; fed by any ForceSensor)."""

from forcelearn.filtering.kalman import ForceFilter, ForceFilterConfig
from forcelearn.filtering.step_filter import MoveAwareForceFilter

__all__ = ["ForceFilter", "ForceFilterConfig", "MoveAwareForceFilter", "make_force_filter"]


def make_force_filter(config: ForceFilterConfig) -> ForceFilter | MoveAwareForceFilter:
    """The filter the config's ``model`` names ("moves" or "stream")."""
    if config.model == "stream":
        return ForceFilter(config)
    return MoveAwareForceFilter(config)
