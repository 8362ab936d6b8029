r"""RAPID data values: evaluate expressions in a scope; read robtarget, wobjdata and tooldata.

=============  =============================================================
robtarget      ``[[x,y,z],[q1,q2,q3,q4],[cf1,cf4,cf6,cfx],[eax_a..eax_f]]``
               mm, unit quaternion with q1 the scalar part; 9E+09 unused axis
wobjdata       ``[robhold, ufprog, ufmec, [[uframe xyz],[q]], [[oframe xyz],[q]]]``
tooldata       ``[robhold, [[tcp xyz],[q]], [mass, [cog xyz], [aom q], ix, iy, iz]]``
``Offs``       ``Offs(p, dx, dy, dz)``: p moved in its work object's frame (mm)
``RelTool``    ``RelTool(p, dx, dy, dz \Rx \Ry \Rz)``: moved in p's own (tool)
               frame, then turned about x, the new y, the new z (deg)
=============  =============================================================

A robtarget stays in its work object's frame here; the reader applies the
work object of the move that uses it.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import TypeAlias

import numpy as np
from scipy.spatial.transform import Rotation

from forcelearn.errors import PathParseError
from forcelearn.paths.rapid_syntax import (
    Aggregate,
    Call,
    Name,
    Node,
    Number,
    Operation,
    Star,
    String,
)
from forcelearn.paths.taught import (
    QUATERNION_TOLERANCE,
    Frame,
    ToolData,
    quaternion_norm_error,
    rotation_from_wxyz,
    wxyz_from_rotation,
)

Value: TypeAlias = float | str | bool | list["Value"]

_IDENTITY: list[Value] = [[0.0, 0.0, 0.0], [1.0, 0.0, 0.0, 0.0]]
PREDEFINED: dict[str, tuple[str, Value]] = {
    "wobj0": ("wobjdata", [False, True, "", _IDENTITY, _IDENTITY]),
    "tool0": ("tooldata", [True, _IDENTITY, [0.001, [0.0, 0.0, 0.001], [1.0, 0.0, 0.0, 0.0],
                                             0.0, 0.0, 0.0]]),
}
"""RAPID's predefined data a program may name without declaring it."""


@dataclass(frozen=True)
class Declaration:
    """A data declaration: ``[LOCAL] CONST|PERS|VAR type name[{dims}] [:= value];``."""

    storage: str
    type_key: str
    name: str
    value: Node | None
    line: int
    source: str


@dataclass(frozen=True)
class Target:
    """A robtarget in its work object's frame: position (mm), quaternion (w, x, y, z)."""

    position_mm: np.ndarray
    quaternion_wxyz: np.ndarray
    rest: list[Value]

    def as_value(self) -> Value:
        """The robtarget as a RAPID aggregate value."""
        return [[float(v) for v in self.position_mm],
                [float(v) for v in self.quaternion_wxyz], *self.rest]


@dataclass
class Scope:
    """The names a PROC sees: its own declarations and assignments, then the module's."""

    source: str
    declarations: dict[str, Declaration]
    parent: Scope | None = None
    assigned: dict[str, Value] = field(default_factory=dict)
    unknown: dict[str, str] = field(default_factory=dict)

    def find(self, key: str) -> tuple[str, Value | None, Declaration | None] | None:
        """(type, assigned value or None, declaration) of ``key``, or None if undeclared."""
        if key in self.declarations:
            declaration = self.declarations[key]
            return declaration.type_key, self.assigned.get(key), declaration
        if self.parent is not None:
            return self.parent.find(key)
        if key in PREDEFINED:
            type_key, value = PREDEFINED[key]
            return type_key, self.assigned.get(key, value), None
        return None

    def assign(self, key: str, value: Value | None, unknown_reason: str = "") -> None:
        """Record what the program assigned to ``key`` (or why its value is now unknown)."""
        if key not in self.declarations and self.parent is not None:
            self.parent.assign(key, value, unknown_reason)
        elif unknown_reason or value is None:
            self.unknown[key] = unknown_reason
            self.assigned.pop(key, None)
        else:
            self.assigned[key] = value
            self.unknown.pop(key, None)

    def why_unknown(self, key: str) -> str | None:
        """Why the value of ``key`` cannot be known when the program reaches here, if so."""
        if key in self.unknown:
            return self.unknown[key]
        return self.parent.why_unknown(key) if self.parent is not None else None


class Evaluator:
    """Evaluates expressions in a scope; raises :class:`PathParseError` naming the line."""

    def __init__(self, scope: Scope, source: str | None = None,
                 visiting: set[str] | None = None) -> None:
        self.scope = scope
        self.source = scope.source if source is None else source
        self._visiting: set[str] = set() if visiting is None else visiting

    def error(self, node: Node, reason: str) -> PathParseError:
        """A parse error at ``node``'s line."""
        return PathParseError(self.source, node.line, reason)

    def typed(self, node: Node, type_key: str) -> Value:
        """The value of a name that must be of RAPID type ``type_key``, or of an aggregate."""
        if isinstance(node, Name):
            found = self.scope.find(node.key)
            if found is None:
                raise self.error(node, f"unknown {type_key} '{node.text}': declare it in "
                                       "the module")
            if found[0] != type_key:
                raise self.error(node, f"'{node.text}' is a {found[0]}, not a {type_key}")
        return self.value(node)

    def value(self, node: Node) -> Value:
        """The value of any expression."""
        if isinstance(node, Number):
            return node.value
        if isinstance(node, String):
            return node.value
        if isinstance(node, Aggregate):
            return [self.value(item) for item in node.items]
        if isinstance(node, Name):
            return self._name(node)
        if isinstance(node, Operation):
            return self._operation(node)
        if isinstance(node, Call) and node.key in ("offs", "reltool"):
            return self.target(node).as_value()
        if isinstance(node, Star):
            raise self.error(node, "an inline '*' target cannot be read: teach it as a robtarget")
        raise self.error(node, f"'{node.text}' is computed by the controller at run time: "
                               "teach the point as a robtarget")

    def written_at(self, node: Node) -> tuple[str, int]:
        """(source, line) where the value of ``node`` was written: its declaration for a name."""
        if isinstance(node, Name) and node.key not in self.scope_assigned_keys():
            found = self.scope.find(node.key)
            if found is not None and found[2] is not None:
                return found[2].source, found[2].line
        return self.source, node.line

    def scope_assigned_keys(self) -> set[str]:
        """Names the program assigned so far (their values come from the PROC)."""
        keys: set[str] = set()
        scope: Scope | None = self.scope
        while scope is not None:
            keys |= set(scope.assigned)
            scope = scope.parent
        return keys

    def number(self, node: Node, what: str) -> float:
        """A numeric expression."""
        value = self.value(node)
        if isinstance(value, bool) or not isinstance(value, float):
            raise self.error(node, f"{what} must be a number, got '{node.text}'")
        if not np.isfinite(value):
            raise self.error(node, f"{what} must be finite, got '{node.text}'")
        return value

    def _name(self, node: Name) -> Value:
        if node.key in ("true", "false") and not node.index:
            return node.key == "true"
        reason = self.scope.why_unknown(node.key)
        if reason is not None:
            raise self.error(node, f"the value of '{node.text}' is not known here: {reason}")
        found = self.scope.find(node.key)
        if found is None:
            raise self.error(node, f"unknown name '{node.text}': declare it in the module")
        _, value, declaration = found
        if value is None and declaration is not None:
            if declaration.value is None:
                raise self.error(node, f"{declaration.name!r} (line {declaration.line}) is "
                                       "declared without a value")
            if node.key in self._visiting:
                raise self.error(node, f"{declaration.name!r} is defined in terms of itself")
            self._visiting.add(node.key)
            try:
                inner = Evaluator(self.scope, declaration.source, self._visiting)
                value = inner.value(declaration.value)
            finally:
                self._visiting.discard(node.key)
        if value is None:
            raise self.error(node, f"'{node.text}' has no value")
        for index in node.index:
            position = self.number(index, "an array index")
            if not isinstance(value, list) or not (1 <= position <= len(value)):
                raise self.error(node, f"'{node.text}': index {position:g} is outside the array")
            value = value[int(position) - 1]
        return value

    def _operation(self, node: Operation) -> float:
        right = self.number(node.right, f"the operand of {node.op!r}")
        if node.left is None:
            return -right if node.op == "-" else right
        left = self.number(node.left, f"the operand of {node.op!r}")
        if node.op == "/":
            if right == 0:
                raise self.error(node, f"division by zero in '{node.text}'")
            return left / right
        return {"+": left + right, "-": left - right, "*": left * right}[node.op]

    def target(self, node: Node) -> Target:
        """A robtarget expression: a name, an aggregate, ``Offs`` or ``RelTool``."""
        if isinstance(node, Call) and node.key == "offs":
            base, dx, dy, dz = self._call_args(node, 4, "Offs(p, dx, dy, dz)")
            offset = np.array([self.number(d, "an Offs distance") for d in (dx, dy, dz)])
            found = self.target(base)
            return Target(found.position_mm + offset, found.quaternion_wxyz, found.rest)
        if isinstance(node, Call) and node.key == "reltool":
            return self._reltool(node)
        value = self.typed(node, "robtarget")
        return robtarget(value, f"robtarget '{node.text}'", self.written_at(node))

    def _call_args(self, node: Call, count: int, form: str) -> tuple[Node, ...]:
        if len(node.args) != count:
            raise self.error(node, f"'{node.text}': expected {form}")
        return node.args

    def _reltool(self, node: Call) -> Target:
        base, dx, dy, dz = self._call_args(node, 4, "RelTool(p, dx, dy, dz [\\Rx] [\\Ry] [\\Rz])")
        unknown = set(node.options) - {"rx", "ry", "rz"}
        if unknown:
            raise self.error(node, f"RelTool takes \\Rx, \\Ry, \\Rz; not {sorted(unknown)}")
        found = self.target(base)
        turn = rotation_from_wxyz(found.quaternion_wxyz)
        offset = np.array([self.number(d, "a RelTool distance") for d in (dx, dy, dz)])
        angles = []
        for axis in ("rx", "ry", "rz"):
            option = node.options.get(axis)
            angles.append(0.0 if option is None else self.number(option, f"RelTool \\{axis}"))
        if any(axis in node.options and node.options[axis] is None for axis in ("rx", "ry", "rz")):
            raise self.error(node, "RelTool's \\Rx, \\Ry, \\Rz need a value (deg)")
        new_turn = turn * Rotation.from_euler("XYZ", angles, degrees=True)
        quaternion = (found.quaternion_wxyz if not any(angles)
                      else wxyz_from_rotation(new_turn))
        return Target(found.position_mm + turn.apply(offset), quaternion, found.rest)

    def frame(self, node: Node) -> Frame:
        """The base-frame frame of a ``wobjdata`` (user frame, then object frame)."""
        value = self.typed(node, "wobjdata")
        shape = "[robhold, ufprog, ufmec, [[x,y,z],[q1..q4]], [[x,y,z],[q1..q4]]]"
        if not (isinstance(value, list) and len(value) == 5):
            raise self.error(node, f"wobjdata '{node.text}' must read {shape}")
        robhold, ufprog = value[0], value[1]
        if robhold is True:
            raise self.error(node, f"wobjdata '{node.text}' is held by the robot (robhold TRUE, "
                                   "a stationary tool): forcelearn follows paths with the tool "
                                   "on the robot")
        if ufprog is False:
            raise self.error(node, f"wobjdata '{node.text}' is moved by a mechanical unit "
                                   "(ufprog FALSE): coordinated motion is not supported")
        at = self.written_at(node)
        user = pose(value[3], f"wobjdata '{node.text}' uframe", at)
        obj = pose(value[4], f"wobjdata '{node.text}' oframe", at)
        return user.then(obj)

    def tool(self, node: Node) -> ToolData:
        """A ``tooldata`` value."""
        value = self.typed(node, "tooldata")
        where = f"tooldata '{node.text}'"
        if not (isinstance(value, list) and len(value) == 3 and isinstance(value[0], bool)
                and isinstance(value[2], list) and len(value[2]) == 6):
            raise self.error(node, f"{where} must read [robhold, [[x,y,z],[q1..q4]], "
                                   "[mass, [cx,cy,cz], [q1..q4], ix, iy, iz]]")
        at = self.written_at(node)
        tcp = pose(value[1], f"{where} tframe", at)
        mass = numbers([value[2][0]], 1, f"{where} mass", at)[0]
        cog = numbers(value[2][1], 3, f"{where} cog", at)
        return ToolData(value[0], tcp, float(mass), (float(cog[0]), float(cog[1]), float(cog[2])))


def numbers(value: Value, count: int, what: str, at: tuple[str, int]) -> np.ndarray:
    """``count`` numbers from a list value, or a parse error at ``at`` (source, line)."""
    if not (isinstance(value, list) and len(value) == count
            and all(isinstance(v, float) for v in value)):
        raise PathParseError(*at, f"{what} must be {count} numbers")
    array = np.array(value, dtype=float)
    if not np.all(np.isfinite(array)):
        raise PathParseError(*at, f"{what} must be finite numbers, got {value}")
    return array


def _unit(quaternion: np.ndarray, what: str, at: tuple[str, int]) -> np.ndarray:
    error = float(quaternion_norm_error(quaternion))
    if not error <= QUATERNION_TOLERANCE:
        raise PathParseError(*at, f"{what}: |q| = {np.linalg.norm(quaternion):.6g} is not a "
                             f"unit quaternion (tolerance {QUATERNION_TOLERANCE:g})")
    return quaternion


def pose(value: Value, what: str, at: tuple[str, int]) -> Frame:
    """A ``pose`` value ``[[x,y,z],[q1..q4]]`` as a frame."""
    if not (isinstance(value, list) and len(value) == 2):
        raise PathParseError(*at, f"{what} must read [[x,y,z],[q1,q2,q3,q4]]")
    position = numbers(value[0], 3, f"{what} position", at)
    quaternion = _unit(numbers(value[1], 4, f"{what} orientation", at), what, at)
    return Frame((float(position[0]), float(position[1]), float(position[2])),
                 (float(quaternion[0]), float(quaternion[1]), float(quaternion[2]),
                  float(quaternion[3])))


def robtarget(value: Value, what: str, at: tuple[str, int]) -> Target:
    """A robtarget value, checked (four parts, a unit quaternion)."""
    if not (isinstance(value, list) and len(value) == 4):
        raise PathParseError(*at, f"{what} must read [[x,y,z],[q1,q2,q3,q4],"
                             "[cf1,cf4,cf6,cfx],[eax_a,...,eax_f]]")
    position = numbers(value[0], 3, f"{what} position", at)
    quaternion = _unit(numbers(value[1], 4, f"{what} orientation", at), what, at)
    numbers(value[2], 4, f"{what} configuration", at)
    numbers(value[3], 6, f"{what} external axes", at)
    return Target(position, quaternion, [value[2], value[3]])
