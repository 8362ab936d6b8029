r"""Read a taught path from RAPID modules: the moves of one PROC, in the base frame.

The reader follows a PROC from top to bottom as the controller would run it
once: each ``MoveL``/``MoveJ`` (and their ``DO``/``Sync``/``AO``/``GO``/``Trigg``
forms, and FC Pressure's ``FCPress1LStart``/``FCPressL``/``FCPressEnd``) gives
its ToPoint, each ``MoveC``/``FCPressC`` its CirPoint then its ToPoint, in the
frame of the ``\WObj`` it names (``wobj0``, the base frame, if none). A call of
another PROC of the program without arguments is followed; an assignment
``p := Offs(p, 0, 0, 10);`` changes what later moves see.

What it refuses (a :class:`PathParseError` with file, line and reason) rather
than guess: a move inside ``IF``/``WHILE``/``FOR``/``TEST`` (the order depends
on run-time values), ``GOTO``, search moves, points computed by the controller
(``CRobT``...), a robot-held work object, an unknown name, a missing PROC.
``MoveAbsJ``/``MoveExtJ`` (joint targets, no pose) are skipped and noted.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from forcelearn.errors import PathParseError
from forcelearn.paths.rapid_syntax import Name, TokenStream, parse_arguments, parse_expression
from forcelearn.paths.rapid_syntax import tokenize as _tokenize
from forcelearn.paths.rapid_values import Declaration, Evaluator, Scope
from forcelearn.paths.taught import Frame, TaughtPath, ToolData

POINTS_PER_MOVE = {
    **dict.fromkeys(("movel", "movej", "moveldo", "movejdo", "movelsync", "movejsync",
                     "movelao", "movejao", "movelgo", "movejgo", "triggl", "triggj",
                     "fcpress1lstart", "fcpressl", "fcpressend"), 1),
    **dict.fromkeys(("movec", "movecdo", "movecsync", "movecao", "movecgo", "triggc",
                     "fcpressc"), 2),
}
"""Motion instructions and how many points (CirPoint, ToPoint) they name first."""

SKIPPED = {"moveabsj": "a joint target", "moveextj": "an external-axes move"}
REFUSED = {
    "searchl": "a search move ends where a signal changes",
    "searchc": "a search move ends where a signal changes",
    "searchj": "a search move ends where a signal changes",
    "goto": "GOTO makes the order of the moves depend on the program's run",
}
_BLOCKS = {"if": "then", "elseif": "then", "while": "do", "for": "do"}
_ENDS = {"endif": "if", "endwhile": "while", "endfor": "for", "endtest": "test"}


@dataclass
class Procedure:
    """A PROC: its name, where its body starts, whether it takes parameters."""

    name: str
    line: int
    body: int
    has_parameters: bool
    stream: TokenStream
    scope: Scope


@dataclass
class Program:
    """The modules read: their procedures (by lower-cased name) and scopes."""

    procedures: dict[str, Procedure] = field(default_factory=dict)
    globals: Scope = field(default_factory=lambda: Scope("", {}))


@dataclass
class Move:
    """One point of the path, in the base frame."""

    position_mm: np.ndarray
    quaternion_wxyz: np.ndarray
    name: str
    line: int
    instruction: str
    tool: str


def read_rapid(paths: str | Path | Sequence[str | Path], proc: str | None = None) -> TaughtPath:
    """Read the path of PROC ``proc`` from one or more RAPID files (``.mod``, ``.modx``, ``.prg``).

    ``proc`` None: ``main`` if the program has it, else its only PROC.
    Raises :class:`PathParseError` naming the file, the line and the reason.
    """
    files = [paths] if isinstance(paths, str | Path) else list(paths)
    texts = []
    for file in files:
        try:
            texts.append((Path(file).read_text(encoding="utf-8-sig"), str(file)))
        except (OSError, UnicodeDecodeError) as exc:
            raise PathParseError(str(file), 0, f"cannot read the RAPID file: {exc}") from exc
    return _read(texts, proc)


def read_rapid_text(text: str, proc: str | None = None, source: str = "<rapid>") -> TaughtPath:
    """Read the path of PROC ``proc`` from RAPID source text (see :func:`read_rapid`)."""
    return _read([(text, source)], proc)


def _read(texts: list[tuple[str, str]], proc: str | None) -> TaughtPath:
    program = Program()
    for text, source in texts:
        _parse_file(TokenStream(_tokenize(text, source), source), program)
    chosen = _choose(program, proc, texts[0][1])
    walker = _Walker(program)
    moves = walker.walk(chosen, ())
    if not moves:
        raise PathParseError(chosen.stream.source, chosen.line,
                             f"PROC {chosen.name} holds no move instruction")
    return TaughtPath(
        np.array([m.position_mm for m in moves]), np.array([m.quaternion_wxyz for m in moves]),
        tuple(m.name for m in moves), tuple(m.line for m in moves),
        source=chosen.stream.source, instructions=tuple(m.instruction for m in moves),
        tool_names=tuple(m.tool for m in moves), tools=walker.tools, notes=tuple(walker.notes),
    )


def _choose(program: Program, proc: str | None, source: str) -> Procedure:
    names = sorted(p.name for p in program.procedures.values())
    if proc is not None:
        if proc.lower() not in program.procedures:
            raise PathParseError(source, 0, f"no PROC {proc!r} in the program; it has: "
                                 f"{', '.join(names) or 'no PROC at all'}")
        return program.procedures[proc.lower()]
    if "main" in program.procedures:
        return program.procedures["main"]
    if len(names) == 1:
        return next(iter(program.procedures.values()))
    raise PathParseError(source, 0, "name the PROC that holds the path; the program has: "
                         f"{', '.join(names) or 'no PROC at all'}")


def _parse_file(stream: TokenStream, program: Program) -> None:
    """Collect a file's declarations and PROCs (bodies are walked later)."""
    module = Scope(stream.source, {}, program.globals)
    local = False
    while stream.peek().kind != "eof":
        token = stream.peek()
        key = token.key
        if key == "module":
            stream.next()
            stream.expect_name("the module's name")
            if stream.accept("("):
                _skip_to(stream, ")")
        elif key == "endmodule":
            stream.next()
        elif key in ("local", "task"):
            stream.next()
            local = key == "local"
            continue
        elif key in ("const", "pers", "var"):
            declaration = _declaration(stream)
            module.declarations[declaration.name.lower()] = declaration
            if not local:
                program.globals.declarations.setdefault(declaration.name.lower(), declaration)
        elif key == "proc":
            procedure = _procedure(stream, module)
            program.procedures[procedure.name.lower()] = procedure
        elif key in ("func", "trap", "record"):
            stream.next()
            _skip_to(stream, "end" + key)
        elif key == "alias":
            _skip_to(stream, ";")
        else:
            raise stream.error(token, f"expected a declaration or a routine, found {token.text!r}"
                               " (a line that does not parse, or a statement outside a PROC)")
        local = False


def _declaration(stream: TokenStream) -> Declaration:
    storage = stream.next().key
    type_key = stream.expect_name("a data type").key
    name = stream.expect_name("the data's name")
    if stream.accept("{"):
        _skip_to(stream, "}")
    value = parse_expression(stream) if stream.accept(":=") else None
    stream.expect(";", f"at the end of the declaration of {name.text}")
    return Declaration(storage, type_key, name.text, value, name.line, stream.source)


def _procedure(stream: TokenStream, module: Scope) -> Procedure:
    stream.next()
    name = stream.expect_name("the PROC's name")
    stream.expect("(", f"after PROC {name.text}")
    has_parameters = not stream.accept(")")
    if has_parameters:
        _skip_to(stream, ")")
    body = stream.at
    _skip_to(stream, "endproc")
    return Procedure(name.text, name.line, body, has_parameters, stream, module)


def _skip_to(stream: TokenStream, key: str) -> None:
    """Consume tokens up to and including the next ``key``; raise at the end of the file."""
    start = stream.peek()
    while stream.peek().kind != "eof":
        if stream.next().key == key:
            return
    raise stream.error(start, f"expected {key.upper() if key.isalpha() else key!r} "
                              "before the end of the file")


class _Walker:
    """Follows PROCs statement by statement and collects their moves."""

    def __init__(self, program: Program) -> None:
        self.program = program
        self.notes: list[str] = []
        self.tools: dict[str, ToolData] = {}

    def walk(self, proc: Procedure, calling: tuple[str, ...]) -> list[Move]:
        """The moves of ``proc``; ``calling`` is the chain of PROCs that called it."""
        if proc.name.lower() in calling:
            raise proc.stream.error(proc.stream.tokens[proc.body], f"PROC {proc.name} calls "
                                    f"itself (through {' -> '.join(calling)}): not a path")
        stream = proc.stream
        stream.at = proc.body
        scope = Scope(stream.source, {}, proc.scope)
        evaluator = Evaluator(scope)
        blocks: list[tuple[str, int]] = []
        moves: list[Move] = []
        while True:
            token = stream.peek()
            key = token.key
            if token.kind == "eof":
                raise stream.error(token, f"PROC {proc.name} has no ENDPROC")
            if key == "endproc" or (key in ("error", "backward", "undo", "return")
                                    and not blocks):
                break
            if key in ("const", "pers", "var"):
                declaration = _declaration(stream)
                scope.declarations[declaration.name.lower()] = declaration
            elif key in _BLOCKS or key == "test":
                self._open(stream, key, blocks)
            elif key in _ENDS:
                stream.next()
                if not blocks or blocks[-1][0] != _ENDS[key]:
                    raise stream.error(token, f"{token.text} without its {_ENDS[key].upper()}")
                blocks.pop()
            elif key in ("else", "default"):
                stream.next()
                stream.accept(":")
            elif key == "case":
                _skip_to(stream, ":")
            elif key in REFUSED:
                raise stream.error(token, f"{token.text}: {REFUSED[key]}; write the path as "
                                          "MoveL/MoveJ/MoveC to taught points")
            elif token.kind == "name" and stream.peek(1).key == ":":
                stream.next()
                stream.next()
            elif _is_assignment(stream):
                self._assign(stream, evaluator, blocks)
            elif key in POINTS_PER_MOVE:
                moves.extend(self._move(stream, evaluator, blocks))
            elif key in SKIPPED:
                _skip_to(stream, ";")
                self.notes.append(f"{stream.source}:{token.line}: {token.text} skipped "
                                  f"({SKIPPED[key]}, no pose to follow)")
            elif key in self.program.procedures:
                moves.extend(self._call(stream, proc, blocks, calling))
            else:
                _skip_to(stream, ";")
        stream.at = proc.body
        return moves

    def _open(self, stream: TokenStream, key: str, blocks: list[tuple[str, int]]) -> None:
        token = stream.next()
        if key == "test":
            blocks.append(("test", token.line))
            while stream.peek().key not in ("case", "default", "endtest", ""):
                stream.next()
            return
        start = stream.at
        while stream.peek().key not in (_BLOCKS[key], ";") and stream.peek().kind != "eof":
            stream.next()
        if stream.peek().key == ";":  # a compact IF: one statement under a condition
            inside = {t.key for t in stream.tokens[start : stream.at]}
            if inside & (set(POINTS_PER_MOVE) | set(self.program.procedures)):
                raise stream.error(token, "a move under a compact IF: the path would depend on "
                                          "the run; write the path as a straight sequence")
            stream.next()
            return
        stream.expect(_BLOCKS[key], f"to open the {key.upper()} block")
        if key == "elseif":
            return
        blocks.append((key, token.line))

    def _assign(self, stream: TokenStream, evaluator: Evaluator,
                blocks: list[tuple[str, int]]) -> None:
        target = stream.next()
        plain = stream.peek().key == ":="
        _skip_to(stream, ":=")
        start = stream.at
        scope = evaluator.scope
        if blocks or not plain:
            _skip_to(stream, ";")
            why = "under " + blocks[-1][0].upper() if blocks else "part by part"
            scope.assign(target.key, None, f"it is assigned {why} at line {target.line}")
            return
        try:
            value = evaluator.value(parse_expression(stream))
            stream.expect(";", "at the end of the assignment")
        except PathParseError as exc:
            stream.at = start
            _skip_to(stream, ";")
            scope.assign(target.key, None, f"it is assigned at line {target.line} a value known "
                                           f"only at run time ({exc.reason})")
            return
        scope.assign(target.key, value)

    def _move(self, stream: TokenStream, evaluator: Evaluator,
              blocks: list[tuple[str, int]]) -> list[Move]:
        token = stream.next()
        if blocks:
            kind, line = blocks[-1]
            raise stream.error(token, f"{token.text} inside {kind.upper()} (line {line}): the "
                                      "order of the moves would depend on the run; write the "
                                      "path as a straight sequence")
        args, options = parse_arguments(stream, ";")
        count = POINTS_PER_MOVE[token.key]
        if len(args) < count:
            raise stream.error(token, f"{token.text} needs {count} point(s) first")
        wobj = options.get("wobj")
        frame = Frame() if wobj is None else evaluator.frame(wobj)
        tool = ""
        for arg in args[count:]:
            found = evaluator.scope.find(arg.key) if isinstance(arg, Name) else None
            if found is not None and found[0] == "tooldata":
                tool = arg.text
                self.tools.setdefault(tool, evaluator.tool(arg))
        moves = []
        for arg in args[:count]:
            target = evaluator.target(arg)
            positions, quaternions = frame.apply(target.position_mm[None, :],
                                                 target.quaternion_wxyz[None, :])
            moves.append(Move(positions[0], quaternions[0], arg.text, arg.line, token.text, tool))
        return moves

    def _call(self, stream: TokenStream, caller: Procedure, blocks: list[tuple[str, int]],
              calling: tuple[str, ...]) -> list[Move]:
        token = stream.next()
        with_arguments = stream.peek().key != ";"
        _skip_to(stream, ";")
        after = stream.at
        callee = self.program.procedures[token.key]
        moves = self.walk(callee, (*calling, caller.name.lower()))
        stream.at = after
        if moves and (blocks or with_arguments or callee.has_parameters):
            why = (f"inside {blocks[-1][0].upper()} (line {blocks[-1][1]})" if blocks
                   else "with arguments")
            raise stream.error(token, f"PROC {callee.name}, which moves, is called {why}: "
                                      "write the path as a straight sequence of moves")
        return moves


def _is_assignment(stream: TokenStream) -> bool:
    r"""``name[...] := value;``: a ``:=`` before the ``;`` that no ``\`` precedes."""
    if stream.peek().kind != "name":
        return False
    ahead = 1
    while True:
        token = stream.peek(ahead)
        if token.key in (";", "\\") or token.kind == "eof":
            return False
        if token.key == ":=":
            return True
        ahead += 1
