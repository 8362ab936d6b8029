"""Gymnasium environments of the paper's tasks.

==========================  =====================================================
id                          what
==========================  =====================================================
``forcelearn/Contour-v0``   §4 two-link contour tracking, pure simulation
                            (:class:`~forcelearn.envs.contour.ContourEnv`)
``forcelearn/Surface-v0``   §5 roller on the sponge, emulated cell through the
                            real drivers, or a real cell from a site config
                            (:class:`~forcelearn.envs.surface.SurfaceEnv`)
``forcelearn/SurfaceVec-v0``  §5 on N emulated cells at once in numpy, the same
                            physics without the wires (``gymnasium.make_vec``
                            with ``vectorization_mode="vector_entry_point"``:
                            :class:`~forcelearn.envs.surface_vec.SurfaceVecEnv`;
                            ``gymnasium.make``: one cell,
                            :class:`~forcelearn.envs.surface_vec.SurfaceSimEnv`)
==========================  =====================================================

Gymnasium ≥ 1.0 loads no plugins by itself; any of these works after
``pip install forcelearn``::

    gymnasium.make("forcelearn.envs:forcelearn/Surface-v0")   # imports this module
    import forcelearn.envs; gymnasium.make("forcelearn/Surface-v0")
    gymnasium.register_envs(forcelearn.envs)                   # keeps linters quiet

Importing this module registers the ids (idempotently), without a
``max_episode_steps``: the environments truncate at the end of their own path.
The classes live in :mod:`forcelearn.envs` (they open cells through the
tools' cell session); this module is their public face.
"""

from __future__ import annotations

from gymnasium.envs.registration import register, registry

from forcelearn.envs.contour import ContourEnv
from forcelearn.envs.surface import SurfaceEnv

CONTOUR_ID = "forcelearn/Contour-v0"
SURFACE_ID = "forcelearn/Surface-v0"
SURFACE_VEC_ID = "forcelearn/SurfaceVec-v0"

__all__ = [
    "CONTOUR_ID", "SURFACE_ID", "SURFACE_VEC_ID", "ContourEnv", "SurfaceEnv", "register_envs",
]


def register_envs() -> None:
    """Register the forcelearn ids with Gymnasium (a second call does nothing)."""
    if CONTOUR_ID not in registry:
        register(CONTOUR_ID, entry_point="forcelearn.envs.contour:ContourEnv")
    if SURFACE_ID not in registry:
        register(SURFACE_ID, entry_point="forcelearn.envs.surface:SurfaceEnv")
    if SURFACE_VEC_ID not in registry:
        register(
            SURFACE_VEC_ID,
            entry_point="forcelearn.envs.surface_vec:SurfaceSimEnv",
            vector_entry_point="forcelearn.envs.surface_vec:SurfaceVecEnv",
        )


register_envs()
