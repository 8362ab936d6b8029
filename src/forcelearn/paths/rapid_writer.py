"""Write a taught path as a RAPID module: robtargets in a work object, and a PROC of MoveL.

The module reads back with :func:`forcelearn.paths.read_rapid` to the same
poses (floats are written with ``repr``). Each robtarget is declared over two
lines, in the style the pendant writes. Arm configuration (cf1, cf4, cf6, cfx)
is not part of a taught path here: it is written as zeros, to be checked on the
pendant before the program runs on a robot.
"""

from __future__ import annotations

import numpy as np

from forcelearn.paths.taught import Frame, TaughtPath, ToolData

_UNUSED_AXES = "[9E+09,9E+09,9E+09,9E+09,9E+09,9E+09]"


def _number(value: float, decimals: int | None) -> str:
    if decimals is None:
        return repr(float(value))
    text = f"{round(float(value), decimals):.{decimals}f}".rstrip("0").rstrip(".")
    return "0" if text in ("-0", "") else text


def _numbers(values: np.ndarray | tuple[float, ...], decimals: int | None = None) -> str:
    return "[" + ",".join(_number(v, decimals) for v in values) + "]"


def _pose(frame: Frame, decimals: int | None) -> str:
    return f"[{_numbers(frame.position_mm, decimals)},{_numbers(frame.quaternion_wxyz, decimals)}]"


def format_rapid_module(
    path: TaughtPath,
    *,
    module: str = "ForcePath",
    proc: str = "main",
    wobj: Frame | None = None,
    wobj_name: str = "wPart",
    tool: ToolData | None = None,
    tool_name: str = "tRoller",
    speed: str = "v50",
    zone: str = "z1",
    point_prefix: str = "p",
    decimals: int | None = None,
) -> str:
    """The RAPID text of ``path`` (base frame), its points written in ``wobj``'s user frame.

    ``decimals``: round every number to that many decimals (None: ``repr``, exact).
    """
    wobj = Frame() if wobj is None else wobj
    tool = tool if tool is not None else ToolData(True, Frame(), 0.001, (0.0, 0.0, 0.001))
    positions, quaternions = wobj.inverse().apply(path.positions_mm, path.quaternions_wxyz)
    names = [name or f"{point_prefix}{10 * (i + 1)}" for i, name in enumerate(path.names)]
    lines = [
        f"MODULE {module}",
        f"  ! {len(path)} points written by forcelearn; poses in mm and unit quaternions (q1 "
        "scalar)",
        f"  PERS tooldata {tool_name} := [{'TRUE' if tool.robhold else 'FALSE'}, "
        f"{_pose(tool.tcp, decimals)},",
        f"    [{tool.mass_kg!r},{_numbers(tool.cog_mm, decimals)},[1,0,0,0],0,0,0]];",
        f"  TASK PERS wobjdata {wobj_name} := [FALSE, TRUE, \"\", {_pose(wobj, decimals)},",
        "    [[0,0,0],[1,0,0,0]]];",
    ]
    for name, position, quaternion in zip(names, positions, quaternions, strict=True):
        lines += [f"  CONST robtarget {name} := [{_numbers(position, decimals)},"
                  f"{_numbers(quaternion, decimals)},",
                  f"    [0,0,0,0],{_UNUSED_AXES}];"]
    lines += ["", f"  PROC {proc}()"]
    lines += [f"    MoveL {name}, {speed}, {zone}, {tool_name} \\WObj:={wobj_name};"
              for name in names]
    lines += ["  ENDPROC", "ENDMODULE", ""]
    return "\n".join(lines)
