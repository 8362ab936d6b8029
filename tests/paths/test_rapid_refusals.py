"""Every RAPID refusal is a PathParseError naming the file, the line and the reason."""

from __future__ import annotations

import contextlib
from pathlib import Path

import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from forcelearn.errors import PathError, PathParseError
from forcelearn.paths import read_rapid, read_rapid_text

AXES = "[9E9,9E9,9E9,9E9,9E9,9E9]"
HEAD = f"""MODULE M
  CONST robtarget p1 := [[0,0,0],[1,0,0,0],[0,0,0,0],{AXES}];
  CONST robtarget p2 := [[10,0,0],[1,0,0,0],[0,0,0,0],{AXES}];
  PERS wobjdata w1 := [FALSE,TRUE,"",[[0,0,0],[1,0,0,0]],[[0,0,0],[1,0,0,0]]];
  VAR num n := 1;
"""
"""Lines 1-5; the cases below start at line 6."""


def _module(body: str, data: str = "") -> str:
    return HEAD + data + "  PROC main()\n" + body + "  ENDPROC\nENDMODULE\n"


CASES = {
    "unknown robtarget": ("    MoveL p9, v10, fine, tool0;\n", "", 7, "unknown robtarget 'p9'"),
    "unknown wobjdata": ("    MoveL p1, v10, fine, tool0 \\WObj:=wX;\n", "", 7,
                         "unknown wobjdata 'wX'"),
    "wrong type": ("    MoveL w1, v10, fine, tool0;\n", "", 7,
                   "'w1' is a wobjdata, not a robtarget"),
    "line that does not parse": ("    MoveL p1, v10, fine, tool0;\n", "  CONST robtarget p3 := "
                                 "[[0,0,0],[1,0,0,0],[0,0,0,0] [9E9]];\n", 6, "expected ']'"),
    "statement outside a PROC": ("    MoveL p1, v10, fine, tool0;\n", "  MoveL p1;\n", 6,
                                 "expected a declaration or a routine"),
    "non-unit quaternion": ("    MoveL p3, v10, fine, tool0;\n", "  CONST robtarget p3 := "
                            f"[[0,0,0],[1,0.2,0,0],[0,0,0,0],{AXES}];\n", 6,
                            "not a unit quaternion"),
    "short robtarget": ("    MoveL p3, v10, fine, tool0;\n", "  CONST robtarget p3 := "
                        "[[0,0,0],[1,0,0,0]];\n", 6, r"must read \[\[x,y,z\]"),
    "move inside IF": ("    IF n = 1 THEN\n      MoveL p1, v10, fine, tool0;\n    ENDIF\n", "", 8,
                       r"MoveL inside IF \(line 7\)"),
    "move inside FOR": ("    FOR i FROM 1 TO 3 DO\n      MoveL p1, v10, fine, tool0;\n    ENDFOR\n",
                        "", 8, "MoveL inside FOR"),
    "move under a compact IF": ("    IF n = 1 MoveL p1, v10, fine, tool0;\n", "", 7,
                                "compact IF"),
    "GOTO": ("    MoveL p1, v10, fine, tool0;\n    GOTO again;\n", "", 8, "GOTO"),
    "search move": ("    SearchL \\Stop, di1, p2, p1, v10, tool0;\n", "", 7, "search move"),
    "point computed at run time": ("    MoveL CRobT(\\Tool:=tool0), v10, fine, tool0;\n", "", 7,
                                   "computed by the controller at run time"),
    "inline star target": ("    MoveL *, v10, fine, tool0;\n", "", 7, r"inline '\*' target"),
    "variable changed under IF": ("    IF n = 1 THEN\n      pv := p2;\n    ENDIF\n"
                                  "    MoveL pv, v10, fine, tool0;\n",
                                  f"  VAR robtarget pv := [[0,0,0],[1,0,0,0],[0,0,0,0],{AXES}];\n",
                                  11, "value of 'pv' is not known here: it is assigned under IF"),
    "declared without a value": ("    MoveL pv, v10, fine, tool0;\n",
                                 "  VAR robtarget pv;\n", 8, "declared without a value"),
    "robot-held work object": ("    MoveL p1, v10, fine, tool0 \\WObj:=wr;\n",
                               "  PERS wobjdata wr := [TRUE,TRUE,\"\",[[0,0,0],[1,0,0,0]],"
                               "[[0,0,0],[1,0,0,0]]];\n", 8, "held by the robot"),
    "RelTool with an unknown option": ("    MoveL RelTool(p1,0,0,1\\Rq:=3), v10, fine, tool0;\n",
                                       "", 7, r"RelTool takes \\Rx, \\Ry, \\Rz"),
    "ENDIF without IF": ("    ENDIF\n    MoveL p1, v10, fine, tool0;\n", "", 7,
                         "ENDIF without its IF"),
    "no move": ("    TPWrite \"nothing\";\n", "", 0, "holds no move instruction"),
}


@pytest.mark.parametrize("case", sorted(CASES))
def test_each_refusal_names_the_line_and_the_reason(case: str) -> None:
    """The message holds the source, the line of the fault and what is wrong."""
    body, data, line, reason = CASES[case]
    text = _module(body, data)
    with pytest.raises(PathParseError, match=reason) as caught:
        read_rapid_text(text, source="cell.mod")
    if case == "no move":  # the PROC's own line
        line = text.splitlines().index("  PROC main()") + 1
    assert caught.value.line == line, str(caught.value)
    assert str(caught.value).startswith(f"cell.mod:{line}: ")


def test_a_missing_proc_and_a_missing_file_are_refused(tmp_path: object) -> None:
    """A PROC the program does not have is named with the ones it has; a missing file too."""
    with pytest.raises(PathParseError, match=r"no PROC 'polish' in the program; it has: main"):
        read_rapid_text(_module("    MoveL p1, v10, fine, tool0;\n"), "polish")
    with pytest.raises(PathParseError, match="cannot read the RAPID file"):
        read_rapid("/nonexistent/cell.mod")


def test_a_proc_that_moves_is_refused_inside_a_loop_or_with_arguments() -> None:
    """A called PROC's moves are followed only where their order is fixed."""
    callee = "  PROC side(num k)\n    MoveL p2, v10, fine, tool0;\n  ENDPROC\n"
    text = _module("    side 1;\n").replace("ENDMODULE", callee + "ENDMODULE")
    with pytest.raises(PathParseError, match="PROC side, which moves, is called with arguments"):
        read_rapid_text(text)
    looping = "  PROC main()\n    WHILE TRUE DO\n      main;\n    ENDWHILE\n  ENDPROC\n"
    with pytest.raises(PathError, match="calls itself"):
        read_rapid_text(HEAD + looping + "ENDMODULE\n")


def test_statements_that_do_not_move_are_passed_over() -> None:
    """I/O, waits, messages, labels, loops without moves and TEST blocks do not stop the reader."""
    body = """    TPWrite "start" \\Num:=n;
    SetDO doTool, 1;
    WaitTime 0.5;
    start:
    TEST n
    CASE 1, 2:
      n := n + 1;
    DEFAULT:
      n := 0;
    ENDTEST
    WHILE n < 3 DO
      n := n + 1;
    ENDWHILE
    MoveL p1, v10, fine, tool0;
    ConfL \\Off;
    MoveL p2, v10, fine, tool0;
"""
    path = read_rapid_text(_module(body))
    assert path.names == ("p1", "p2")


MODULES = sorted((Path(__file__).parent / "modules").glob("*.mod"))
PIECES = ["[", "]", ",", ";", ":=", "\\", "!", '"', "*", "\n", "9E+999", "MoveL ", "ENDPROC",
          "IF x THEN ", "ENDIF", "Offs(", "RelTool(", "\\WObj:=", "PROC p()", "-"]


@settings(max_examples=60)
@given(st.sampled_from(MODULES), st.lists(st.tuples(st.floats(0, 1), st.integers(0, 12),
                                                     st.sampled_from(PIECES)), max_size=4))
def test_a_damaged_module_is_read_or_refused_never_crashes(
    module: Path, edits: list[tuple[float, int, str]]
) -> None:
    """Deleting and inserting pieces anywhere gives a path or a PathParseError, nothing else."""
    text = module.read_text(encoding="utf-8-sig")
    for where, cut, piece in edits:
        at = int(where * len(text))
        text = text[:at] + piece + text[at + cut:]
    with contextlib.suppress(PathParseError):
        read_rapid_text(text)
