"""Grammar-aware mutations of every input kind, as hypothesis strategies.

A :class:`Case` is a set of files (written into a fresh folder) and the ``roar-verify``
arguments that read them. :func:`cases` draws one: an input kind, a bundled seed file of
that kind, and a few mutations that know the kind's grammar:

* text languages (``.clf`` models, ``.roar`` specs): token-level deletion, duplication,
  swaps, replacement by the language's keywords and operators, deep nesting, huge
  numbers, stray and non-UTF-8 bytes, truncation, lines spliced from another file;
* TOML (jobs, properties, scenarios, TCA models): values replaced by values of another
  type, huge or non-finite numbers, deeply nested arrays and inline tables, keys removed
  or duplicated, plus the text mutations;
* traces (JSON Lines): fields of the wrong type, removed fields, deep nesting, huge and
  ``1e999999999`` numbers, headers whose fields are wrong, lines dropped or swapped;
* structural faults: a folder, a FIFO or ``/dev/zero`` where a file is expected, output
  paths under a file, on a folder, or unwritable.

``Case.expect_location`` is the oracle for located errors: set when the mutated text no
longer parses as TOML or JSON by Python's own readers, which then know a line and column
(the error ``roar-verify`` prints must carry ``file:line``).
"""

from __future__ import annotations

import json
import re
import tomllib
from dataclasses import dataclass, field
from functools import lru_cache
from pathlib import Path

from hypothesis import strategies as st

ROOT = Path(__file__).resolve().parents[2]

#: requests of the bundled specs (a spec is checked and compiled on its request)
REQUESTS = {
    "mutual_make.roar": "arm::started == true",
    "mutual_make_fixed.roar": "arm::started == true",
    "ordered_pick.roar": "picker::done == true",
    "ordered_pick_fixed.roar": "picker::done == true",
    "retry_bounded.roar": "mission::done == true",
    "retry_forever.roar": "mission::done == true",
    "conflict.roar": "mission::done == true",
    "door_nav.roar": "base::arrived == true where base::gx == 9.0 && base::gy == 3.0",
}

BOUNDS = ["--max-states", "40", "--max-seconds", "3"]

CLF_WORDS = ["type", "kind", "->", "-o", "-@", "@", "{", "}", "(", ")", "*", "!", "1", "\\", "=", ".", ":", ",",
             "#exec", "#query", "#trace", "#mode", "Pi", "Exists", "nat", "z", "s", "<-", "o-", "&", "+", "T",
             "#exec *", "#query * 1 *", "%", "%{", "}%", "_", "X", "[", "]", "<", ">", "'"]
ROAR_WORDS = ["ability", "task", "recipe", "pre", "post", "body", "recipes", "tasks", "context", "make", "ensure",
              "wait", "set", "bool", "int", "float", "true", "false", "==", "!=", "<=", ">=", "&&", "||", "!",
              "::", "{", "}", "(", ")", ";", ",", "=", "+", "-", "*", "/", "where", "if", "else", "primitive",
              "//", "/*", "*/", "\"", "1.5", "-0", "assert", "loop"]
TOML_VALUES = ['""', '"x"', "0", "-1", "1.5", "true", "[]", "{}", "[1, \"a\"]", '{a = 1}', "nan", "inf", "-inf",
               "1979-05-27", "1e400", "0x7fffffff", '"../../etc/passwd"', '"/dev/zero"', '"."', "[[]]",
               '"\\u0000"', '"' + "x" * 300 + '"']
HUGE_NUMBERS = ["9" * 5000, "-" + "9" * 5000, "1e5000", "1e999999999", "-1e999999999", "1" + "0" * 40,
                "0." + "0" * 4000 + "1", "NaN", "Infinity", "-0", "4294967297", "18446744073709551617"]
BYTES = [b"\x00", b"\xff\xfe", b"\xc3\x28", b"\xed\xa0\x80", b"\r", b"\t", b"\x1b[31m", "\u202e".encode(),
         "é".encode(), b"\xf0\x9f\xa4\x96"]

_TOKEN = re.compile(r'\s+|"(?:[^"\\\n]|\\.)*"|[A-Za-z_#][A-Za-z0-9_\']*|\d+(?:\.\d+)?|::|->|-o|==|!=|<=|>=|&&|\|\||.',
                    re.S)


@dataclass
class Case:
    """One fuzzing input: files to write (name -> bytes) and the arguments that read them."""

    kind: str
    seed: str
    argv: list
    files: dict = field(default_factory=dict)
    mutations: list = field(default_factory=list)
    expect_location: bool = False
    target: str = ""   # the mutated file's name (in the case folder)
    special: dict = field(default_factory=dict)   # name -> "fifo" | "dir" | "devzero" | "readonly-dir"

    def describe(self) -> str:
        return f"{self.kind} from {self.seed}: {'; '.join(self.mutations) or 'unmutated'}; argv {self.argv}"


# ------------------------------------------------------------------ seeds

@lru_cache(maxsize=None)
def seeds(kind: str) -> tuple:
    """The bundled files of an input kind: ((name, text), ...)."""
    def read(paths):
        return tuple((str(p.relative_to(ROOT)), p.read_text(encoding="utf-8")) for p in sorted(paths))

    if kind == "clf":
        return read(list((ROOT / "models/clf").glob("*.clf")) + list((ROOT / "models/philosophers").glob("*.clf")))
    if kind == "roar":
        return read(p for p in list((ROOT / "models").glob("*.roar")) + list((ROOT / "models/faulty").glob("*.roar"))
                    if p.name in REQUESTS)
    if kind == "job":
        out = []
        for name, text in read((ROOT / "checker").glob("*.toml")):
            out.append((name, re.sub(r'"\.\./', f'"{ROOT}/', text)))
        return tuple(out)
    if kind == "property":
        return read((ROOT / "properties").glob("*.toml"))
    if kind == "scenario":
        return read((ROOT / "models/scenarios").glob("*.toml"))
    if kind == "tca-model":
        return read([ROOT / "models/ambler/ambler.toml"])
    if kind == "tca-trace":
        return read(list((ROOT / "models/ambler/traces").glob("*.jsonl"))
                    + [p for p in (ROOT / "tests/tca/traces").glob("*.jsonl") if "ok" in p.name])
    if kind == "trace":
        return (("(generated) mutual_make.deadlock.jsonl", counterexample_trace()),)
    raise ValueError(kind)


@lru_cache(maxsize=None)
def counterexample_trace() -> str:
    """A real counterexample trace of checker/mutual_make.toml (computed once per process)."""
    import tempfile

    from ..verify.check import run_job, save_counterexample
    from ..verify.jobs import load_job
    res = run_job(load_job(ROOT / "checker/mutual_make.toml"))
    with tempfile.TemporaryDirectory() as d:
        return save_counterexample(res, "deadlock", Path(d)).read_text(encoding="utf-8")


KINDS = ("clf", "roar", "job", "property", "scenario", "tca-model", "tca-trace", "trace")


# ------------------------------------------------------------------ text mutations

def _tokens(text: str) -> list[str]:
    return _TOKEN.findall(text)


@st.composite
def _text_mutation(draw, data: bytes, words: list[str]) -> tuple[bytes, str]:
    """One token-level mutation of ``data`` (bytes in, bytes out, and its description)."""
    text = data.decode("utf-8", errors="surrogateescape")
    toks = _tokens(text)
    if not toks:
        toks = [""]
    n = len(toks)
    op = draw(st.sampled_from(["delete", "duplicate", "swap", "replace", "insert", "nest", "huge-number",
                               "bytes", "truncate", "splice-lines", "delete-line", "repeat-line", "empty"]))
    i = draw(st.integers(0, n - 1))
    j = draw(st.integers(0, n - 1))
    if op == "delete":
        k = draw(st.integers(1, 4))
        del toks[i:i + k]
        desc = f"delete {k} token(s) at {i}"
    elif op == "duplicate":
        toks[i:i] = toks[i:i + draw(st.integers(1, 6))]
        desc = f"duplicate tokens at {i}"
    elif op == "swap":
        toks[i], toks[j] = toks[j], toks[i]
        desc = f"swap tokens {i} and {j}"
    elif op == "replace":
        w = draw(st.sampled_from(words + HUGE_NUMBERS[:3] + [t for t in toks if t.strip()][:50]))
        toks[i] = w if len(w) < 80 else w[:5000]
        desc = f"replace token {i} with {w[:20]!r}"
    elif op == "insert":
        w = draw(st.sampled_from(words))
        toks.insert(i, " " + w + " ")
        desc = f"insert {w!r} at {i}"
    elif op == "nest":
        depth = draw(st.sampled_from([3, 50, 1000, 20000]))
        o, c = draw(st.sampled_from([("(", ")"), ("{", "}"), ("[", "]"), ("!", ""), ("-", ""), ("(", "")]))
        toks.insert(i, o * depth + draw(st.sampled_from(["x", "1", "true", "a::b == 1"])) + c * depth)
        desc = f"nest {o}{c} {depth} deep at {i}"
    elif op == "huge-number":
        w = draw(st.sampled_from(HUGE_NUMBERS))
        nums = [k for k, t in enumerate(toks) if t[:1].isdigit()]
        k = draw(st.sampled_from(nums)) if nums else i
        toks[k] = w
        desc = f"number at token {k} -> {w[:12]}...({len(w)} chars)"
    elif op == "bytes":
        b = draw(st.sampled_from(BYTES))
        raw = "".join(toks).encode("utf-8", errors="surrogateescape")
        at = draw(st.integers(0, len(raw)))
        return raw[:at] + b + raw[at:], f"insert bytes {b!r} at byte {at}"
    elif op == "truncate":
        raw = "".join(toks).encode("utf-8", errors="surrogateescape")
        at = draw(st.integers(0, len(raw)))
        return raw[:at], f"truncate at byte {at}"
    elif op in ("splice-lines", "delete-line", "repeat-line"):
        lines = "".join(toks).split("\n")
        a = draw(st.integers(0, len(lines) - 1))
        if op == "delete-line":
            del lines[a]
        elif op == "repeat-line":
            lines[a:a] = [lines[a]] * draw(st.sampled_from([2, 100]))
        else:
            b = draw(st.integers(0, len(lines) - 1))
            lines.insert(a, lines[b])
        desc = f"{op} at line {a + 1}"
        return "\n".join(lines).encode("utf-8", errors="surrogateescape"), desc
    else:
        return b"", "empty file"
    return "".join(toks).encode("utf-8", errors="surrogateescape"), desc


@st.composite
def _toml_mutation(draw, data: bytes) -> tuple[bytes, str]:
    """A mutation that knows TOML: a value of another type, a key removed or duplicated, deep nesting."""
    text = data.decode("utf-8", errors="surrogateescape")
    lines = text.split("\n")
    assigns = [k for k, ln in enumerate(lines) if re.match(r"\s*[A-Za-z0-9_\"\-.]+\s*=", ln)]
    if not assigns:
        return draw(_text_mutation(data, ["=", "[", "]", "[[", "]]"] + TOML_VALUES))
    k = draw(st.sampled_from(assigns))
    key, _, _old = lines[k].partition("=")
    op = draw(st.sampled_from(["retype", "retype", "huge", "nest-array", "nest-table", "remove", "duplicate",
                               "new-key", "table-header"]))
    if op == "retype":
        v = draw(st.sampled_from(TOML_VALUES))
        lines[k] = f"{key}= {v}"
    elif op == "huge":
        v = draw(st.sampled_from(["9" * 5000, "-" + "9" * 5000, "1e5000", "1e999999999", "1" + "0" * 30,
                                  '"' + "9" * 5000 + '"']))
        lines[k] = f"{key}= {v}"
    elif op == "nest-array":
        d = draw(st.sampled_from([5, 500, 5000]))
        lines[k] = f"{key}= {'[' * d}1{']' * d}"
    elif op == "nest-table":
        d = draw(st.sampled_from([5, 500, 3000]))
        lines[k] = f"{key}= {'{a = ' * d}1{' }' * d}"
    elif op == "remove":
        del lines[k]
    elif op == "duplicate":
        lines.insert(k, lines[k])
    elif op == "new-key":
        lines.insert(k, f"{draw(st.sampled_from(['bogus', 'name', 'spec', 'model', 'start', 'check']))} = "
                        f"{draw(st.sampled_from(TOML_VALUES))}")
    else:
        lines.insert(k, draw(st.sampled_from(["[bounds]", "[expect]", "[[wall]]", "[model]", "[sizes]",
                                              "[x]", "[[x]]", "[bounds.inner]"])))
    return "\n".join(lines).encode("utf-8", errors="surrogateescape"), f"toml {op} at line {k + 1}"


def _wrong(draw, value):
    """A JSON value of another type (or a pathological one)."""
    return draw(st.sampled_from([
        None, True, -1, 0, 2 ** 70, 1.5, "x", "", [], {}, [1, [2]], {"a": {"b": 1}},
        "NaN", "9" * 5000, {"step": 1}, [None] * 3]))


@st.composite
def _jsonl_mutation(draw, data: bytes) -> tuple[bytes, str]:
    text = data.decode("utf-8", errors="surrogateescape")
    lines = [ln for ln in text.split("\n") if ln.strip()]
    op = draw(st.sampled_from(["field-type", "field-type", "remove-field", "deep", "huge-raw", "drop-line",
                               "swap-lines", "duplicate-line", "not-object", "text"]))
    if not lines or op == "text":
        return draw(_text_mutation(data, ['"', "{", "}", "[", "]", ":", ",", "null", "true", "1e999999999"]))
    k = draw(st.integers(0, len(lines) - 1))
    try:
        rec = json.loads(lines[k])
    except (ValueError, RecursionError):   # a line an earlier mutation broke or nested deeply
        rec = None
    if op in ("field-type", "remove-field") and isinstance(rec, dict) and rec:
        key = draw(st.sampled_from(sorted(rec)))
        if op == "field-type":
            rec[key] = _wrong(draw, rec[key])
        else:
            del rec[key]
        lines[k] = json.dumps(rec)
        desc = f"line {k + 1}: {op} {key!r}"
    elif op == "deep":
        d = draw(st.sampled_from([50, 2000, 100000]))
        key = draw(st.sampled_from(sorted(rec))) if isinstance(rec, dict) and rec else "x"
        inner = "[" * d + "1" + "]" * d if draw(st.booleans()) else '{"a": ' * d + "1" + "}" * d
        lines[k] = json.dumps({**(rec if isinstance(rec, dict) else {}), key: 0})[:-1].rsplit(
            json.dumps(key) + ": 0", 1)[0] + json.dumps(key) + ": " + inner + "}"
        desc = f"line {k + 1}: {key!r} nested {d} deep"
    elif op == "huge-raw":
        nums = list(re.finditer(r"(?<![\w.\"])-?\d+(\.\d+)?(?![\w\"])", lines[k]))
        w = draw(st.sampled_from(HUGE_NUMBERS[:6] + ["1e308", "-1e-400", "1E+99999"]))
        if nums:
            m = draw(st.sampled_from(nums))
            lines[k] = lines[k][:m.start()] + w + lines[k][m.end():]
        else:
            lines[k] = lines[k].rstrip("}") + f', "time": {w}}}'
        desc = f"line {k + 1}: number -> {w[:12]}"
    elif op == "drop-line":
        del lines[k]
        desc = f"drop line {k + 1}"
    elif op == "swap-lines":
        j = draw(st.integers(0, len(lines) - 1))
        lines[k], lines[j] = lines[j], lines[k]
        desc = f"swap lines {k + 1} and {j + 1}"
    elif op == "duplicate-line":
        lines.insert(k, lines[k])
        desc = f"duplicate line {k + 1}"
    else:
        lines[k] = json.dumps(_wrong(draw, rec))
        desc = f"line {k + 1}: not an object"
    return ("\n".join(lines) + "\n").encode("utf-8", errors="surrogateescape"), desc


# ------------------------------------------------------------------ cases

def _argv(kind: str, seed: str, target: str, draw) -> tuple[list, dict]:
    """The command that reads the mutated file ``target``, and the other files it needs."""
    extra: dict = {}
    mm = str(ROOT / "models/faulty/mutual_make.roar")
    if kind == "clf":
        return ["check", target, *BOUNDS, "--no-traces"], extra
    if kind == "roar":
        req = REQUESTS[Path(seed).name]
        fn = ROOT / Path(seed).with_suffix(".py")
        if fn.exists():
            extra[Path(target).with_suffix(".py").name] = fn.read_bytes()
        if draw(st.booleans()):
            return ["compile", target, "-r", req], extra
        return ["check", target, "-r", req, *BOUNDS, "--no-traces"], extra
    if kind == "job":
        return ["check", target, *BOUNDS, "--no-traces"], extra
    if kind == "property":
        extra["job.toml"] = (f'name = "fuzz"\nspec = "{mm}"\nrequest = "arm::started == true"\n'
                             f'properties = ["{target}"]\n').encode()
        return ["check", "job.toml", *BOUNDS, "--no-traces"], extra
    if kind == "scenario":
        return ["simulate", str(ROOT / "models/door_nav.roar"), "-s", target, "-r", REQUESTS["door_nav.roar"],
                "--max-steps", "60"], extra
    if kind == "tca-model":
        return ["tca-simulate", target, "--out", "out.jsonl"], extra
    if kind == "tca-trace":
        return ["tca-check", target], extra
    if kind == "trace":
        return ["replay", target, "--model", mm], extra
    raise ValueError(kind)


def _located_oracle(kind: str, data: bytes) -> bool:
    """Does the mutated file carry an error Python's own reader can locate (TOML, JSON)?"""
    try:
        text = data.decode("utf-8")
    except UnicodeDecodeError:
        return False
    if kind in ("job", "property", "scenario", "tca-model"):
        try:
            tomllib.loads(text)
        except tomllib.TOMLDecodeError:
            return True
        except (RecursionError, ValueError):
            return False
        return False
    if kind in ("trace", "tca-trace"):
        for ln in text.splitlines():
            if not ln.strip():
                continue
            try:
                json.loads(ln)
            except json.JSONDecodeError:
                return True
            except (RecursionError, ValueError):
                return False
        return False
    return False


STRUCTURAL = ("input-is-folder", "input-is-fifo", "input-is-dev-zero", "missing-input", "output-under-file",
              "output-is-folder", "output-unwritable", "html-under-file", "png-is-file")


@st.composite
def _structural(draw) -> Case:
    """A fault in the file system rather than in a file's text."""
    fault = draw(st.sampled_from(STRUCTURAL))
    kind = draw(st.sampled_from(["clf", "roar", "job", "tca-model", "tca-trace", "trace", "scenario"]))
    seed, text = draw(st.sampled_from(seeds(kind)))
    target = "input" + (Path(seed).suffix or ".txt")
    argv, extra = _argv(kind, seed, target, draw)
    case = Case(kind=kind, seed=seed, argv=argv, files={target: text.encode(), **extra}, mutations=[fault],
                target=target)
    if fault == "input-is-folder":
        case.files.pop(target)
        case.special[target] = "dir"
    elif fault == "input-is-fifo":
        case.files.pop(target)
        case.special[target] = "fifo"
    elif fault == "input-is-dev-zero":
        case.argv = [a if a != target else "/dev/zero" for a in argv]
    elif fault == "missing-input":
        case.files.pop(target)
    else:
        mm = str(ROOT / "models/faulty/mutual_make.roar")
        case.files["afile"] = b"x"
        case.special["ro"] = "readonly-dir"
        out = {"output-under-file": "afile/sub/out", "output-is-folder": ".", "output-unwritable": "ro/sub/out",
               "html-under-file": "afile/html", "png-is-file": "afile"}[fault]
        choice = draw(st.sampled_from(["compile", "tca-simulate", "check-html", "check-png", "check-traces",
                                       "simulate-trace"]))
        if fault.startswith("html"):
            choice = "check-html"
        if fault == "png-is-file":
            choice = "check-png"
        case.kind, case.seed = "output", choice
        if choice == "compile":
            case.argv = ["compile", mm, "-r", "arm::started == true", "-o", out]
        elif choice == "tca-simulate":
            case.argv = ["tca-simulate", str(ROOT / "models/ambler/ambler.toml"), "--out", out]
        elif choice == "check-html":
            case.argv = ["check", str(ROOT / "checker/mutual_make.toml"), "--html", out, *BOUNDS]
        elif choice == "check-png":
            case.argv = ["check", str(ROOT / "checker/mutual_make.toml"), "--png", out, *BOUNDS]
        elif choice == "check-traces":
            case.argv = ["check", str(ROOT / "checker/mutual_make.toml"), "--traces", out, *BOUNDS]
        else:
            case.argv = ["simulate", str(ROOT / "models/door_nav.roar"), "-s", str(ROOT / "models/scenarios/door.toml"),
                         "-r", REQUESTS["door_nav.roar"], "--max-steps", "20", "--trace", out]
    return case


@st.composite
def cases(draw, kinds: tuple = KINDS, structural: float = 0.08) -> Case:
    """A fuzzing case: a bundled input of one of ``kinds``, mutated 1 to 3 times (or a structural fault)."""
    if draw(st.floats(0, 1)) < structural:
        return draw(_structural())
    kind = draw(st.sampled_from(kinds))
    seed, text = draw(st.sampled_from(seeds(kind)))
    data = text.encode("utf-8")
    descs = []
    for _ in range(draw(st.integers(1, 3))):
        if kind in ("job", "property", "scenario", "tca-model"):
            data, d = draw(st.one_of(_toml_mutation(data), _text_mutation(data, ["=", "[", "]", "\""] + TOML_VALUES)))
        elif kind in ("trace", "tca-trace"):
            data, d = draw(_jsonl_mutation(data))
        else:
            data, d = draw(_text_mutation(data, CLF_WORDS if kind == "clf" else ROAR_WORDS))
        descs.append(d)
    target = "input" + Path(seed).suffix
    argv, extra = _argv(kind, seed, target, draw)
    return Case(kind=kind, seed=seed, argv=argv, files={target: data, **extra}, mutations=descs,
                expect_location=_located_oracle(kind, data), target=target)
