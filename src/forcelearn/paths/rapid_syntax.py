r"""RAPID's lexical layer and expressions: tokens with line numbers, and an expression tree.

Only what a taught program needs: identifiers (case-insensitive, as in RAPID),
numbers (``9E+09``, ``-1.5e-3``), strings, aggregates ``[...]``, array
elements ``p{3}``, function calls with optional arguments
(``RelTool(p, 0, 0, 5 \Rz:=30)``) and the arithmetic ``+ - * /`` on numbers.
``!`` starts a comment to the end of the line; the ``%%%`` header block of
old ``.prg`` files is skipped. Every token and node carries its 1-based line.
"""

from __future__ import annotations

import re
from collections.abc import Callable
from dataclasses import dataclass, field

from forcelearn.errors import PathParseError

_TOKEN = re.compile(
    r"""
    (?P<space>[ \t\r\f\v]+)
  | (?P<newline>\n)
  | (?P<comment>![^\n]*)
  | (?P<num>(?:\d+\.?\d*|\.\d+)(?:[eE][+-]?\d+)?)
  | (?P<name>[A-Za-z_][A-Za-z0-9_]*)
  | (?P<str>"(?:[^"\n]|"")*")
  | (?P<op>:=|<>|<=|>=|[\[\]{}(),;\\:=+\-*/<>.%])
    """,
    re.VERBOSE,
)


@dataclass(frozen=True)
class Token:
    """One token: ``kind`` is name, num, str, op or eof; ``key`` is the lower-cased text."""

    kind: str
    text: str
    line: int

    @property
    def key(self) -> str:
        """The text as RAPID compares it (identifiers are case-insensitive)."""
        return self.text.lower()


def tokenize(text: str, source: str) -> list[Token]:
    """The tokens of a RAPID file, comments and the ``%%%`` header removed, then an eof token."""
    text = _blank_header(text)
    tokens: list[Token] = []
    line, at = 1, 0
    while at < len(text):
        match = _TOKEN.match(text, at)
        if match is None:
            raise PathParseError(source, line, f"unexpected character {text[at]!r}")
        kind = match.lastgroup or ""
        if kind == "newline":
            line += 1
        elif kind not in ("space", "comment"):
            tokens.append(Token(kind, match.group(), line))
        at = match.end()
    tokens.append(Token("eof", "", line))
    return tokens


def _blank_header(text: str) -> str:
    """Replace an old-style ``%%%`` ... ``%%%`` header by blank lines (keeps line numbers)."""
    lines = text.split("\n")
    marks = [i for i, line in enumerate(lines) if line.strip() == "%%%"]
    if len(marks) >= 2:
        for i in range(marks[0], marks[1] + 1):
            lines[i] = ""
    return "\n".join(lines)


@dataclass(frozen=True)
class Node:
    """An expression node; ``text`` is its source, as it reads in a message."""

    line: int
    text: str


@dataclass(frozen=True)
class Number(Node):
    """A numeric literal."""

    value: float


@dataclass(frozen=True)
class String(Node):
    """A string literal (quotes removed)."""

    value: str


@dataclass(frozen=True)
class Name(Node):
    """An identifier, optionally indexed: ``p10`` or ``path{3}``."""

    key: str
    index: tuple[Node, ...] = ()


@dataclass(frozen=True)
class Aggregate(Node):
    """``[a, b, ...]``."""

    items: tuple[Node, ...]


@dataclass(frozen=True)
class Call(Node):
    r"""``Func(positional..., \Option:=value, \Switch)``; option keys lower-cased."""

    key: str
    args: tuple[Node, ...]
    options: dict[str, Node | None] = field(default_factory=dict)


@dataclass(frozen=True)
class Operation(Node):
    """A unary (``left`` None) or binary arithmetic operation."""

    op: str
    left: Node | None
    right: Node


@dataclass(frozen=True)
class Star(Node):
    """The ``*`` of an old inline target the pendant hid."""


class TokenStream:
    """A cursor over tokens that raises :class:`PathParseError` naming the line."""

    def __init__(self, tokens: list[Token], source: str) -> None:
        self.tokens = tokens
        self.source = source
        self.at = 0

    def peek(self, ahead: int = 0) -> Token:
        """The token ``ahead`` places on (eof at the end)."""
        return self.tokens[min(self.at + ahead, len(self.tokens) - 1)]

    def next(self) -> Token:
        """Consume and return the next token."""
        token = self.peek()
        self.at = min(self.at + 1, len(self.tokens) - 1)
        return token

    def accept(self, text: str) -> bool:
        """Consume the next token if its key is ``text`` (lower case)."""
        if self.peek().key == text and self.peek().kind in ("op", "name"):
            self.next()
            return True
        return False

    def expect(self, text: str, what: str) -> Token:
        """Consume ``text`` or raise naming what was expected."""
        token = self.peek()
        if not self.accept(text):
            found = token.text or "end of file"
            raise self.error(token, f"expected {text!r} {what}, found {found!r}")
        return token

    def expect_name(self, what: str) -> Token:
        """Consume an identifier or raise."""
        token = self.next()
        if token.kind != "name":
            raise self.error(token, f"expected {what}, found {token.text or 'end of file'!r}")
        return token

    def error(self, token: Token, reason: str) -> PathParseError:
        """A parse error at ``token``'s line."""
        return PathParseError(self.source, token.line, reason)

    def text_since(self, start: int) -> str:
        """The source text of the tokens consumed since index ``start``."""
        out = ""
        for token in self.tokens[start : self.at]:
            out += token.text + (" " if token.text == "," else "")
        return out


def parse_expression(stream: TokenStream) -> Node:
    """``term (('+'|'-') term)*``."""
    return _binary(stream, ("+", "-"), _term)


def _term(stream: TokenStream) -> Node:
    """``factor (('*'|'/') factor)*``."""
    return _binary(stream, ("*", "/"), _factor)


def _binary(
    stream: TokenStream, ops: tuple[str, str], operand: Callable[[TokenStream], Node]
) -> Node:
    """``operand (op operand)*`` for ``op`` in ``ops``, left-associative."""
    start = stream.at
    node = operand(stream)
    while stream.peek().key in ops and stream.peek().kind == "op":
        op = stream.next().text
        right = operand(stream)
        node = Operation(node.line, stream.text_since(start), op, node, right)
    return node


def _factor(stream: TokenStream) -> Node:
    start, token = stream.at, stream.peek()
    if token.kind == "op" and token.text in ("-", "+"):
        stream.next()
        operand = _factor(stream)
        return Operation(token.line, stream.text_since(start), token.text, None, operand)
    return _primary(stream)


def _primary(stream: TokenStream) -> Node:
    start, token = stream.at, stream.next()
    if token.kind == "num":
        return Number(token.line, token.text, float(token.text))
    if token.kind == "str":
        return String(token.line, token.text, token.text[1:-1].replace('""', '"'))
    if token.text == "*":
        return Star(token.line, "*")
    if token.text == "[":
        items = _list(stream, "]")
        return Aggregate(token.line, stream.text_since(start), tuple(items))
    if token.text == "(":
        inner = parse_expression(stream)
        stream.expect(")", "to close the parenthesis")
        return inner
    if token.kind == "name":
        if stream.accept("{"):
            index = _list(stream, "}")
            return Name(token.line, stream.text_since(start), token.key, tuple(index))
        if stream.accept("("):
            args, options = parse_arguments(stream, ")")
            return Call(token.line, stream.text_since(start), token.key, tuple(args), options)
        return Name(token.line, token.text, token.key)
    raise stream.error(token, f"expected a value, found {token.text or 'end of file'!r}")


def _list(stream: TokenStream, close: str) -> list[Node]:
    items = [parse_expression(stream)]
    while stream.accept(","):
        items.append(parse_expression(stream))
    stream.expect(close, "to close the list")
    return items


def parse_arguments(stream: TokenStream, close: str) -> tuple[list[Node], dict[str, Node | None]]:
    r"""Arguments up to ``close`` (consumed): positional ones, and ``\Name[:=value]`` options.

    An optional argument may stand alone between commas (``\Conc,``) or follow a
    positional one (``v100 \T:=5``), as RAPID allows.
    """
    args: list[Node] = []
    options: dict[str, Node | None] = {}
    if stream.accept(close):
        return args, options
    while True:
        _options(stream, options)
        if stream.peek().key not in (",", close) or stream.peek().kind != "op":
            args.append(parse_expression(stream))
            _options(stream, options)
        if stream.accept(close):
            return args, options
        stream.expect(",", "between arguments")


def _options(stream: TokenStream, options: dict[str, Node | None]) -> None:
    while stream.accept("\\"):
        name = stream.expect_name("an optional argument's name after '\\'")
        options[name.key] = parse_expression(stream) if stream.accept(":=") else None
