"""Parser for Celf's concrete syntax, producing :mod:`roar_formal.clf.surface` trees.

The grammar lives in ``celf.lark`` next to this module. It is compiled once,
lazily, into a lark LALR(1) parser with the contextual lexer; the tree is built
during parsing by an inline transformer (no intermediate lark tree), which
keeps large files fast. Every lark error is turned into a
:class:`~roar_formal.errors.SyntaxError_` with a position and a message in
terms of the source text, never lark's terminal names.
"""

from __future__ import annotations

import contextvars
import dataclasses
import functools
import re
from fractions import Fraction
from importlib import resources
from os import PathLike
from typing import Iterable, Union

from lark import Lark, Token, Transformer
from lark.lexer import Lexer
from lark.exceptions import UnexpectedEOF, UnexpectedInput, UnexpectedToken

from ..errors import Pos, RoarError, SyntaxError_, TypeError_
from . import surface as s

__all__ = ["parse_program", "parse_file", "parse_expr"]

# The inline transformer is fixed when the parser is built, so the file name
# for positions travels through a context variable set around each parse.
_FILE: contextvars.ContextVar[str] = contextvars.ContextVar("celf_file", default="<input>")


def _tpos(tok: Token) -> Pos:
    return Pos(_FILE.get(), tok.line, tok.column)


def _bound(tok: Token) -> s.Bound:
    return "*" if tok.type == "STAR" else int(tok)


_MODE_NAME = {"linear": "", "affine": "@", "persistent": "!"}


def _desugar_pattern(binder: str, pat, ty, body):
    """``PI p : S. B`` and ``EXISTS p : S1. S2`` in terms of Pi, Exists, the arrows and ``*``.

    A pattern must follow the shape of its type: ``!x`` binds a persistent
    ``!A`` (dependently, as ``Pi x:A`` / ``Exists x:A``); ``_``, ``@_``, ``!_``
    match ``A``, ``@A``, ``!A`` without binding; ``1`` matches ``1`` and
    ``[p, q]`` a tensor ``S1 * S2``.
    """
    if isinstance(pat, s.PVar):
        if pat.mode != "persistent":
            raise SyntaxError_(
                f"'{_MODE_NAME[pat.mode]}{pat.name}' cannot be bound by {binder}: a variable of a {binder} pattern "
                f"is persistent ('!{pat.name} : !A'); write '_' or '@_' for a part that is not named", pat.pos)
        if not isinstance(ty, s.Bang):
            raise TypeError_(f"the pattern '!{pat.name}' of {binder} needs a type '!A'", ty.pos)
        cls = s.Pi if binder == "PI" else s.Exists
        return cls(pat.pos, pat.name, ty.body, body)
    if isinstance(pat, s.PBlank):
        want = {"persistent": s.Bang, "affine": s.Affine}.get(pat.mode)
        if want is not None and not isinstance(ty, want):
            mark = "!" if pat.mode == "persistent" else "@"
            raise TypeError_(f"the pattern '{mark}_' of {binder} needs a type '{mark}A'", ty.pos)
        if want is None and isinstance(ty, (s.Bang, s.Affine, s.Tensor, s.One, s.Exists)):
            raise TypeError_(f"the pattern '_' of {binder} needs a negative type (write '!_', '@_', '1' or "
                             "'[p, q]' to match '!A', '@A', '1' or 'S1 * S2')", ty.pos)
        if binder == "EXISTS":
            return s.Tensor(pat.pos, ty, body)
        if want is None:
            return s.Arrow(pat.pos, "-o", ty, body)
        return s.Arrow(pat.pos, "->" if pat.mode == "persistent" else "-@", ty.body, body)
    if isinstance(pat, s.POne):
        if not isinstance(ty, s.One):
            raise TypeError_(f"the pattern '1' of {binder} needs the type '1'", ty.pos)
        return body
    # a tuple [p1, p2, ..., pn] matches S1 * (S2 * ...); its variables are checked in the order
    # written, so that the first wrong one is the one reported
    stack = list(reversed(pat.items))
    while stack:
        item = stack.pop()
        if isinstance(item, s.PTuple):
            stack.extend(reversed(item.items))
        elif isinstance(item, s.PVar) and item.mode != "persistent":
            return _desugar_pattern(binder, item, ty, body)
    first, rest = pat.items[0], pat.items[1:]
    if not isinstance(ty, s.Tensor):
        raise TypeError_(f"the pattern '[...]' of {binder} needs a tensor type 'S1 * S2'", ty.pos)
    rest_pat = rest[0] if len(rest) == 1 else s.PTuple(rest[0].pos, rest)
    inner = _desugar_pattern(binder, rest_pat, ty.right, body)
    return _desugar_pattern(binder, first, ty.left, inner)


_UNESCAPE = {"\\": "\\", '"': '"', "n": "\n", "r": "\r", "t": "\t"}
_ESCAPE_RE = re.compile(r"\\(.)")


def _unescape(tok: str) -> str:
    """The value of a string literal token (the lexer admits only the five escapes)."""
    return _ESCAPE_RE.sub(lambda m: _UNESCAPE[m[1]], tok[1:-1])


_ARROW_OPS = {"-o": "-o", "->": "->", "-@": "-@", "o-": "-o", "<-": "->", "@-": "-@"}


class _Build(Transformer):
    """Turns each grammar rule into a surface node as soon as it is reduced.

    A node's position is that of its first token: either a token child or the
    position of its first child node.
    """

    # -- atoms ------------------------------------------------------------
    def ident(self, c):
        return s.Id(_tpos(c[0]), str(c[0]))

    def type_kw(self, c):
        return s.TypeKw(_tpos(c[0]))

    def one(self, c):
        return s.One(_tpos(c[0]))

    def num_lit(self, c):
        return s.Num(_tpos(c[0]), Fraction(str(c[0])), str(c[0]))

    def str_lit(self, c):
        return s.Str(_tpos(c[0]), _unescape(str(c[0])))

    def underscore(self, c):
        return s.Underscore(_tpos(c[0]))

    def paren(self, c):
        # ``(M)`` is M itself, but positioned at the '(' so that the node's
        # position is still the first token of the text it was read from.
        node = dataclasses.replace(c[1], pos=_tpos(c[0]))
        # the item being read keeps it: a #query tells `(1 a)` (its type) from `1 a` (a fifth bound)
        self.__dict__.setdefault("_parened", {})[id(node)] = node
        return node

    def _item_read(self) -> dict:
        """The parenthesised nodes of the item just read, forgotten for the next item (kept
        alive until then, so that no other node takes one's id)."""
        return self.__dict__.pop("_parened", None) or {}

    def annot(self, c):
        return s.Annot(_tpos(c[0]), c[1], c[2])

    def monad(self, c):
        return s.Monad(_tpos(c[0]), c[1])

    def pair(self, c):
        return s.Pair(_tpos(c[0]), c[1], c[2])

    def proj(self, c):
        body, tok = c
        return s.Proj(body.pos, body, int(tok[1]))

    # -- application and prefixes ----------------------------------------
    def apply(self, c):
        if len(c) == 2:
            return s.App(c[0].pos, c[0], c[1])
        fn, mark, arg = c
        return s.App(fn.pos, fn, arg, str(mark))

    def prefix(self, c):
        tok, body = c
        cls = s.Bang if tok.type == "BANG" else s.Affine
        return cls(_tpos(tok), body)

    # -- binary operators -------------------------------------------------
    def conj(self, c):
        left, op, right = c
        cls = s.Tensor if op.type == "STAR" else s.With
        return cls(left.pos, left, right)

    def arrow(self, c):
        left, op, right = c
        return s.Arrow(left.pos, _ARROW_OPS[str(op)], left, right)

    def rev_arrow(self, c):
        concl, op, premise = c
        return s.Arrow(concl.pos, _ARROW_OPS[str(op)], premise, concl, reversed=True)

    # -- binders ----------------------------------------------------------
    def binder_ty(self, c):
        return c[0] if c else None

    def lam_mark(self, c):
        return c[0] if c else None

    def pi(self, c):
        kw, var, ty, body = c
        return s.Pi(_tpos(kw), str(var), ty, body)

    def exists(self, c):
        kw, var, ty, body = c
        return s.Exists(_tpos(kw), str(var), ty, body)

    def lam(self, c):
        kw, pat, ty, body = c
        if isinstance(pat, s.PVar):
            return s.Lam(_tpos(kw), pat.name, body, pat.mode, ty)
        return s.PatLam(_tpos(kw), pat, ty, body)

    def let(self, c):
        kw, _brace, pat, value, _in, body = c
        return s.Let(_tpos(kw), pat, value, body)

    def tuple(self, c):
        return s.Tuple(_tpos(c[0]), tuple(c[1:]))

    # -- patterns -----------------------------------------------------------
    def pat_var(self, c):
        if len(c) == 1:
            return s.PVar(_tpos(c[0]), str(c[0]), "linear")
        mark, name = c
        return s.PVar(_tpos(mark), str(name), "persistent" if mark.type == "BANG" else "affine")

    def pat_blank(self, c):
        if len(c) == 1:
            return s.PBlank(_tpos(c[0]), "linear")
        return s.PBlank(_tpos(c[0]), "persistent" if c[0].type == "BANG" else "affine")

    def pat_one(self, c):
        return s.POne(_tpos(c[0]))

    def pat_tuple(self, c):
        return s.PTuple(_tpos(c[0]), tuple(c[1:]))

    def pat_paren(self, c):
        return dataclasses.replace(c[1], pos=_tpos(c[0]))

    def pat_pi(self, c):
        kw, pat, ty, body = c
        return _desugar_pattern("PI", pat, ty, body)

    def pat_exists(self, c):
        kw, pat, ty, body = c
        return _desugar_pattern("EXISTS", pat, ty, body)

    # -- items ------------------------------------------------------------
    def decl(self, c):
        self._item_read()
        name = c[0]
        definition = c[2] if len(c) == 3 else None
        return s.Decl(_tpos(name), str(name), c[1], definition)

    def query(self, c):
        kw, d, e, l, a, goal = c
        parened = self._item_read()
        head, bare = goal, id(goal) not in parened   # (parenthesised on the way down: the goal's head)
        while isinstance(head, s.App):
            head = head.fn
            bare = bare and id(head) not in parened
        if bare and s.headed_by_number(goal):
            # `#query * 1 * 1 1 a.`: a fifth bound read as the type's head (Celf's parser refuses it too)
            raise SyntaxError_("a #query has four bounds (depth, expected solutions, solutions to look "
                               "for, attempts) and then its type; this one has a fifth bound", head.pos)
        # Celf checks the bounds when the query runs, after its type (see query.run_query)
        return s.Query(_tpos(kw), _bound(d), _bound(e), _bound(l), _bound(a), goal,
                       bounds_pos=tuple(_tpos(b) for b in (d, e, l, a)))

    def exec(self, c):
        self._item_read()
        kw, n, start = c
        return s.Exec(_tpos(kw), _bound(n), start, trace=kw.type == "TRACE")

    def mode(self, c):
        kw, name, *modes = c
        return s.Mode(_tpos(kw), str(name), tuple(str(m) for m in modes))

    def implicit_modes(self, c):
        return tuple(str(m) for m in c[1:])

    def mode_implicit(self, c):
        kw, name, implicit, *modes = c
        return s.Mode(_tpos(kw), str(name), tuple(str(m) for m in modes), implicit)

    def program(self, c):
        self._item_read()
        return tuple(c)

    def lone_expr(self, c):
        self._item_read()
        return c[0]


# ---------------------------------------------------------------------------
# The lexer: Celf's lexical rules
# ---------------------------------------------------------------------------

#: the characters of an identifier (Celf's lexer: any run of them is one token)
ID_CHARS = "-a-zA-Z0-9<>=/|_'*#+&~;$?"
_WORD_RE = r"[\-a-zA-Z0-9<>=/|_'*#+&~;$?]"
_SCAN = re.compile(
    r"(?P<ws>[ \t\r\n\f]+)"
    r"|(?P<block>%\{.*?\}%)"
    r"|(?P<openblock>%\{)"
    r"|(?P<line>%[^\n]*)"
    r"|(?P<affi>-@)"
    # a decimal literal (an extension): digits, '.', digits, not running into an identifier
    r"|(?P<dec>-?[0-9]+\.[0-9]+(?!" + _WORD_RE + r"))"
    r"|(?P<word>" + _WORD_RE + r"+)"
    r'|(?P<str>"(?:[^"\\\n]|\\["\\nrt])*")'
    r"|(?P<raffi>@-)"
    r"|(?P<punct>[.:{}()\[\],\\!@])",
    re.S)
_PUNCT = {".": "_DOT", ":": "_COLON", "{": "LBRACE", "}": "_RBRACE", "(": "LPAR", ")": "_RPAR",
          "[": "LBRACKET", "]": "_RBRACKET", ",": "_COMMA", "\\": "LAMBDA", "!": "BANG", "@": "AT"}
# a run of identifier characters that is exactly one of these is that token
_WORDS = {
    "-o": "LOLLI", "o-": "RLOLLI", "->": "ARROW", "<-": "RARROW", "-D": "MINUSD", "_": "UNDERSCORE",
    "&": "AMP", "*": "STAR", "<": "LANGLE", ">": "_RANGLE", "=": "_EQUAL", "+": "PLUS", "-": "MINUS",
    "type": "TYPE", "Pi": "PI", "PI": "LPI", "Exists": "EXISTS", "EXISTS": "LEXISTS", "let": "LET",
    "in": "IN", "#1": "PROJ", "#2": "PROJ", "#query": "QUERY", "#mode": "MODE", "#exec": "EXEC",
    "#trace": "TRACE", "1": "ONE",
}
_DIGITS = re.compile(r"[0-9]+")
_NEG_INT = re.compile(r"-[0-9]+")


def is_identifier_word(w: str) -> bool:
    """Does the lexer read ``w`` alone as an identifier (not a keyword, a number or an operator)?"""
    return _word_type(w) == "ID"


def _word_type(w: str) -> str:
    kind = _WORDS.get(w)
    if kind is not None:
        return kind
    if _DIGITS.fullmatch(w):
        return "NUM"
    if _NEG_INT.fullmatch(w):
        return "NUMLIT"  # an extension: Celf reads `-1` as an identifier
    return "ID"


def tokenize(text: str, file: str = "<input>"):
    """Celf's tokens of ``text`` as lark tokens (whitespace and comments dropped).

    Malformed input (an unterminated comment or string, a character outside
    the language) raises a positioned :class:`SyntaxError_`.
    """
    pos = 0
    line = 1
    line_start = 0
    n = len(text)
    scan = _SCAN.match
    while pos < n:
        m = scan(text, pos)
        if m is None:
            col = pos - line_start + 1
            raise SyntaxError_(_bad_characters(text, pos), Pos(file, line, col))
        kind = m.lastgroup
        end = m.end()
        value = m.group()
        if kind == "ws" or kind == "block" or kind == "line":
            nl = value.count("\n")
            if nl:
                line += nl
                line_start = pos + value.rfind("\n") + 1
            pos = end
            continue
        col = pos - line_start + 1
        if kind == "word":
            ttype = _word_type(value)
        elif kind == "punct":
            ttype = _PUNCT[value]
        elif kind == "affi":
            ttype = "AFFI"
        elif kind == "raffi":
            ttype = "RAFFI"
        elif kind == "dec":
            ttype = "NUMLIT"
        elif kind == "str":
            ttype = "STRING"
        else:  # openblock
            raise SyntaxError_("unterminated block comment: '%{' has no matching '}%'", Pos(file, line, col))
        yield Token(ttype, value, pos, line, col, line, col + len(value), end)
        pos = end


class _CelfLexer(Lexer):
    """Feeds :func:`tokenize`'s tokens to lark's LALR parser."""

    def __init__(self, conf):
        pass

    def lex(self, data, parser_state=None):
        # lark hands a custom lexer the text (a str, or a TextSlice in lark >= 1.2)
        while not isinstance(data, str):
            data = data.text
        return tokenize(data, _FILE.get())


@functools.cache
def _parser() -> Lark:
    """Build the LALR parser once (grammar analysis is the expensive part)."""
    grammar = resources.files(__package__).joinpath("celf.lark").read_text(encoding="utf-8")
    options = dict(parser="lalr", lexer=_CelfLexer, start=["program", "lone_expr"], transformer=_Build(),
                   maybe_placeholders=False)
    try:
        # lark keeps the analysed grammar in a cache file (keyed by the grammar's text), which
        # saves most of the start-up of `roar-verify clf` on a small program
        return Lark(grammar, cache=True, **options)
    except Exception:  # pragma: no cover - an unwritable or stale cache: analyse afresh
        return Lark(grammar, **options)


def _run(text: str, file: str, start: str):
    token = _FILE.set(file)
    try:
        return _parser().parse(text, start=start)
    except UnexpectedInput as e:
        err = _convert(e, text, file)
    finally:
        _FILE.reset(token)
    raise err from None


#: the longest run of digits read as a number (Python converts at most 4,300 digits)
MAX_DIGITS = 4000
_LONG_DIGITS = re.compile(r"[0-9]{%d,}" % (MAX_DIGITS + 1))


def _check_digits(text: str, file: str) -> None:
    """Refuse, at its place, a number too long to read (before the parser converts it)."""
    m = _LONG_DIGITS.search(text)
    if m:
        line = text.count("\n", 0, m.start()) + 1
        col = m.start() - (text.rfind("\n", 0, m.start()) + 1) + 1
        raise SyntaxError_(f"a number of {len(m.group(0)):,} digits: at most {MAX_DIGITS:,} are read",
                           Pos(file, line, col))


def parse_program(text: str, file: str = "<input>") -> s.Program:
    """Parse a whole Celf file (declarations and directives)."""
    _check_digits(text, file)
    return s.Program(file, _run(text, file, "program"))


def parse_expr(text: str, file: str = "<input>") -> s.Expr:
    """Parse a single expression (no trailing '.')."""
    _check_digits(text, file)
    return _run(text, file, "lone_expr")


def parse_file(path: Union[str, PathLike]) -> s.Program:
    """Read a UTF-8 file and parse it; unreadable files are user errors, not crashes."""
    name = str(path)
    from ..inputs import check_input_file
    check_input_file(path)
    try:
        with open(path, encoding="utf-8-sig") as f:
            text = f.read()
    except FileNotFoundError:
        raise RoarError(f"cannot read {name}: no such file") from None
    except IsADirectoryError:
        raise RoarError(f"cannot read {name}: it is a directory") from None
    except UnicodeDecodeError as e:
        raise RoarError(f"cannot read {name}: not valid UTF-8 (byte {e.start})") from None
    except OSError as e:
        raise RoarError(f"cannot read {name}: {e.strerror or e}") from None
    return parse_program(text, name)


# ---------------------------------------------------------------------------
# Error messages
# ---------------------------------------------------------------------------

_LITERAL = {
    "TYPE": "type", "PI": "Pi", "EXISTS": "Exists", "UNDERSCORE": "_", "ONE": "1",
    "RLOLLI": "o-", "RARROW": "<-", "RAFFI": "@-", "LOLLI": "-o", "ARROW": "->", "AFFI": "-@",
    "STAR": "*", "AMP": "&", "PLUS": "+", "MINUS": "-", "BANG": "!", "AT": "@", "LAMBDA": "\\",
    "LPAR": "(", "_RPAR": ")", "LBRACE": "{", "_RBRACE": "}", "LANGLE": "<", "_RANGLE": ">",
    "_COMMA": ",", "_COLON": ":", "_EQUAL": "=", "_DOT": ".",
    "QUERY": "#query", "EXEC": "#exec", "TRACE": "#trace", "MODE": "#mode",
    "LPI": "PI", "LEXISTS": "EXISTS", "LET": "let", "IN": "in", "MINUSD": "-D",
    "LBRACKET": "[", "_RBRACKET": "]",
}
_EXPR_START = {"ID", "TYPE", "PI", "EXISTS", "UNDERSCORE", "ONE", "NUM", "NUMLIT", "STRING", "BANG", "AT", "LAMBDA",
               "LPAR", "LBRACE", "LANGLE", "LPI", "LEXISTS", "LET", "LBRACKET", "PLUS", "MINUS", "MINUSD"}
_OPERATORS = {"RLOLLI", "RARROW", "RAFFI", "LOLLI", "ARROW", "AFFI", "STAR", "AMP"}
_ARROWS = _OPERATORS - {"STAR"}  # '*' is also a bound and a mode
_DIRECTIVES = {"QUERY", "EXEC", "TRACE", "MODE"}
_CLOSERS = ["_DOT", "_RPAR", "_RBRACE", "_RBRACKET", "_RANGLE", "_COMMA", "_COLON", "_EQUAL"]
_OPENER_OF = {"_RPAR": "LPAR", "_RBRACE": "LBRACE", "_RANGLE": "LANGLE", "_RBRACKET": "LBRACKET"}
_CLOSER_OF = {v: k for k, v in _OPENER_OF.items()}
_IGNORED = {"WS", "LINE_COMMENT", "BLOCK_COMMENT"}
_BOUND_HINT = {
    "QUERY": "#query takes four bounds before its goal: depth, expected solutions, "
             "solutions per attempt and attempts",
    "EXEC": "#exec takes a step bound before its start type",
    "TRACE": "#trace takes a step bound before its start type",
}
_OTHER = {"NUM": "a natural number", "PROJ": "'#1' or '#2'", "NUMLIT": "a number", "STRING": "a string"}
_WORD = re.compile(_WORD_RE + "*")


def _found(tok: Token) -> str:
    """Describe the offending token as the user wrote it."""
    if tok.type == "$END":
        return "end of file"
    if tok.type == "ID":
        return f"identifier '{tok}'"
    if tok.type in ("NUM", "NUMLIT", "ONE") and tok.type in ("NUM", "NUMLIT"):
        return f"number {tok}"
    if tok.type == "STRING":
        return f"string {tok}"
    if tok.type in ("TYPE", "PI", "EXISTS", "LPI", "LEXISTS", "LET", "IN"):
        return f"keyword '{tok}'"
    if tok.type in _DIRECTIVES:
        return f"directive '{tok}'"
    return f"'{tok}'"


def _expected(names: Iterable[str]) -> str:
    """Summarise an expected-terminal set in a few human words."""
    names = set(names) - _IGNORED
    parts: list[str] = []
    if names >= {"ID", "LPAR"}:
        # After a complete expression the parser also takes arguments and operators.
        parts += ["an argument", "an operator"] if names & _OPERATORS else ["an expression"]
        names -= _EXPR_START | _OPERATORS | {"PROJ"}
    elif names & _DIRECTIVES and "ID" in names:
        parts += ["a declaration 'name : type.'", "a directive (#query, #exec, #trace, #mode)"]
        names -= _DIRECTIVES | {"ID"}
    if {"NUM", "ONE"} <= names and not names & _ARROWS and "ID" not in names:
        parts.append("a natural number or '*'" if "STAR" in names else "a natural number")
        names -= {"NUM", "ONE", "STAR"}
    if {"PLUS", "MINUS", "STAR"} <= names:
        parts.append("a mode ('+', '-', '-D' or '*')")
        names -= {"PLUS", "MINUS", "MINUSD", "STAR"}
    if "ID" in names:
        parts.append("an identifier")
    for n in _CLOSERS:
        if n in names:
            parts.append(f"'{_LITERAL[n]}'")
    for n in sorted(names - {"ID", "$END"} - set(_CLOSERS)):
        parts.append(f"'{_LITERAL[n]}'" if n in _LITERAL else _OTHER.get(n, n.lower()))
    if "$END" in names:
        parts.append("end of file")
    if not parts:
        return "nothing more here"
    return parts[0] if len(parts) == 1 else ", ".join(parts[:-1]) + " or " + parts[-1]


def _accepted(e: UnexpectedToken) -> set[str]:
    """The terminals the parser would accept here.

    LALR states are shared between contexts, so lark's own ``expected`` set can
    be a union over all of them (e.g. ')' outside any parenthesis); asking the
    interactive parser which tokens it really accepts gives the precise set.
    """
    ip = getattr(e, "interactive_parser", None)
    if ip is not None:
        try:
            return set(ip.accepts()) - _IGNORED
        except Exception:  # pragma: no cover - fall back on lark's estimate
            pass
    return set(e.expected or ()) - _IGNORED


def _stack(e: UnexpectedInput) -> list:
    """The parser's value stack at the error (tokens not yet reduced, and nodes)."""
    ip = getattr(e, "interactive_parser", None)
    try:
        return list(ip.parser_state.value_stack) if ip is not None else []
    except AttributeError:  # pragma: no cover - lark internals changed
        return []


def _hints(e: UnexpectedToken, expected: set[str], text: str) -> list[str]:
    """Explanations for the common mistakes, read off the parser's stack."""
    tok = e.token
    stack = _stack(e)
    toks = [v for v in stack if isinstance(v, Token)]
    last = stack[-1] if stack else None
    hints: list[str] = []

    # Unclosed or unmatched brackets.
    open_ = [t for t in toks if t.type in _CLOSER_OF]
    if tok.type in _OPENER_OF:
        opener = _OPENER_OF[tok.type]
        if not any(t.type == opener for t in open_):
            hints.append(f"there is no open '{_LITERAL[opener]}' for this '{tok}' to close")
    elif open_ and _CLOSER_OF[open_[-1].type] in expected:
        o = open_[-1]
        hints.append(f"the '{o}' at {o.line}:{o.column} is not closed")
        # Twelf's binder {X:A} B: in Celf, braces are the monad, and a binder is written Pi
        name = text[o.end_pos:tok.start_pos].strip() if o.end_pos is not None and tok.start_pos is not None else ""
        if str(o) == "{" and tok.type == "_COLON" and re.fullmatch(_WORD_RE + "+", name):
            hints.append(f"Twelf's '{{{name}:A}} B' is written 'Pi {name}:A. B' in Celf (braces are the monad)")

    # A bound of #query/#exec/#trace that is not a number.
    if {"NUM", "ONE"} <= expected and not expected & _ARROWS and "ID" not in expected:
        directive = next((t for t in reversed(toks) if t.type in _DIRECTIVES), None)
        if directive is not None and directive.type in _BOUND_HINT:
            hints.append(_BOUND_HINT[directive.type])

    # A binder without its variable or its body.
    if isinstance(last, Token):
        before = stack[-2] if len(stack) > 1 else None
        after_mark = last.type in ("BANG", "AT") and isinstance(before, Token) and before.type == "LAMBDA"
        if last.type in ("PI", "EXISTS", "LAMBDA", "LPI", "LEXISTS") or after_mark:
            binder = before if after_mark else last
            hints.append(f"'{binder}' must be followed by the name of the variable it binds")
        elif last.type == "_DOT" and tok.type in ("$END", "_DOT", "_RPAR", "_RBRACE", "_RANGLE", "_COMMA"):
            binder = next((t for t in reversed(toks) if t.type in ("PI", "EXISTS", "LAMBDA")), None)
            if binder is not None:
                hints.append(f"the '{binder}' at {binder.line}:{binder.column} has no body after its '.'")
        elif last.type in _OPERATORS and tok.type in _CLOSERS + ["$END"]:
            hints.append(f"'{last}' needs an expression on its right")

    # A declaration or directive that is missing its final '.'.
    if "_DOT" in expected and not hints:
        if tok.type == "$END":
            hints.append("every declaration and directive ends with '.'")
        elif tok.type in _DIRECTIVES or (tok.type in ("_COLON", "_EQUAL") and _starts_line(tok, text)):
            hints.append("is the '.' ending the previous declaration missing?")
    return hints


def _starts_line(tok: Token, text: str) -> bool:
    """Is ``tok`` preceded on its line only by an identifier (``name :`` at line start)?"""
    start = tok.start_pos if tok.start_pos is not None else 0
    line_start = text.rfind("\n", 0, start) + 1
    return re.fullmatch(r"\s*" + _WORD_RE + r"+\s*", text[line_start:start]) is not None


def _convert(e: UnexpectedInput, text: str, file: str) -> SyntaxError_:
    """Turn any lark parse error into a positioned SyntaxError_ with a readable message."""
    if isinstance(e, UnexpectedToken):
        tok = e.token
        expected = _accepted(e)
        stack = _stack(e)
        last = stack[-1] if stack else None
        if isinstance(last, Token) and last.type == "ID" and last.startswith("#") and expected == {"_COLON"}:
            return SyntaxError_(f"unknown directive '{last}'; the directives are #query, #exec, #trace and #mode",
                                Pos(file, last.line, last.column))
        if tok.type == "$END":
            line, col = (tok.end_line, tok.end_column) if tok.end_line else (tok.line, tok.column)
        else:
            line, col = tok.line, tok.column
        msg = f"unexpected {_found(tok)}; expected {_expected(expected)}"
        hints = _hints(e, expected, text)
        if hints:
            msg += " (" + "; ".join(hints) + ")"
        return SyntaxError_(msg, Pos(file, line or 1, col or 1))
    if isinstance(e, UnexpectedEOF):  # not raised by LALR, but be safe
        return SyntaxError_("unexpected end of file", Pos(file, *_end(text)))
    return SyntaxError_(f"syntax error: {e}", Pos(file, getattr(e, "line", 1) or 1,
                                                   getattr(e, "column", 1) or 1))


def _bad_characters(text: str, pos: int) -> str:
    """Message for text that no token of the language matches at all."""
    rest = text[pos:]
    if rest.startswith('"'):
        return _bad_string(rest)
    ch = rest[:1]
    shown = repr(ch) if not ch.isprintable() or ch in "'\\" else f"'{ch}'"
    return (f"illegal character {shown}; an identifier is a run of letters, digits and the characters "
            f"- < > = / | _ ' * # + & ~ ; $ ?")


def _bad_string(rest: str) -> str:
    line = rest.split("\n", 1)[0]
    i = 1
    while i < len(line):
        c = line[i]
        if c == '"':
            break
        if c == "\\":
            esc = line[i:i + 2]
            if esc[1:] not in ('"', "\\", "n", "r", "t"):
                return (f"invalid escape '{esc}' in a string literal; the escapes are "
                        "'\\\"', '\\\\', '\\n', '\\r' and '\\t'")
            i += 2
            continue
        i += 1
    return "unterminated string literal: a string must end with '\"' on the line it starts"


def _end(text: str) -> tuple[int, int]:
    lines = text.split("\n")
    return len(lines), len(lines[-1]) + 1
