"""The Gymnasium environments' classes (public ids and registration: :mod:`forcelearn.envs`)."""

from forcelearn.tools.envs.contour import ContourEnv
from forcelearn.tools.envs.surface import SurfaceEnv

__all__ = ["ContourEnv", "SurfaceEnv"]
