"""Old names kept for one release: a module ``__getattr__`` that warns and resolves them.

When a device's names are made one (``robot_controller`` -> ``computer_link``,
``EgmRobotDriver`` -> ``EgmRobot``...), the module that defines the new object
keeps the old name importable for one release::

    __getattr__ = renamed(__name__, {"EgmRobotDriver": EgmRobot})

Reading the old name gives the new object and a :class:`DeprecationWarning`
naming its replacement.
"""

from __future__ import annotations

import warnings
from collections.abc import Callable, Mapping


def renamed(module: str, names: Mapping[str, object]) -> Callable[[str], object]:
    """A module ``__getattr__``: each old name in ``names`` warns and gives its new object."""

    def getattr_(name: str) -> object:
        if name not in names:
            raise AttributeError(f"module {module!r} has no attribute {name!r}")
        new = names[name]
        where = f"{getattr(new, '__module__', module)}.{getattr(new, '__name__', name)}"
        warnings.warn(f"{module}.{name} is deprecated: use {where} (the old name goes in the "
                      "next release)", DeprecationWarning, stacklevel=2)
        return new

    return getattr_
