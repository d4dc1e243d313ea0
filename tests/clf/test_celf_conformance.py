"""Celf conformance (issue 13): every program of ``tests/clf/celf_conformance/`` through
``roar-verify clf``, checked against the answer Celf gives, written in its header.

Header lines (``%`` comments at the top of each file):

* ``% construct:`` / ``% behaviour:`` what it tests; ``% celf:`` Celf's answer in words
  (derived by hand: the suite runs without Celf);
* ``% expect: ok`` (exit 0), or ``% expect: CATEGORY LINE:COL FRAGMENT`` with CATEGORY one of
  ``parse error``, ``type error``, ``mode error``, ``general error`` (Celf's "Error in query":
  malformed bounds), ``query failed`` (exit 2, a located message
  of that class containing FRAGMENT, no traceback); a known deviation says
  ``% expect: unsupported LINE:COL FRAGMENT`` and ``% deviation:`` why;
* ``% output: LINE`` a line the run must print (repeatable), ``% absent: TEXT`` text it must not;
  ``% proof: LINE`` a line the run must print with ``--proof`` (Celf's solution term);
* ``% seeds: 0 1 2`` run once per scheduler seed, each with the same outcome.
"""

from __future__ import annotations

import re
from pathlib import Path

import pytest

from roar_formal.cli import main
from roar_formal.cli.clf import celf_category
from roar_formal.clf.query import run_file, with_big_stack
from roar_formal.errors import RoarError, UnsupportedError
from repo import ROOT

HERE = Path(__file__).resolve().parent / "celf_conformance"
CASES = sorted(HERE.glob("*.clf"))
EXPECT = re.compile(r"(ok|parse error|type error|mode error|general error|query failed|unsupported)(?:\s+(\d+):(\d+)\s+(.*\S))?$")


def header(path: Path) -> dict:
    h: dict = {"output": [], "absent": [], "proof": [], "seeds": [0]}
    for line in path.read_text(encoding="utf-8").splitlines():
        if not line.startswith("%"):
            break
        m = re.match(r"%\s*(\w+):\s?(.*)$", line)
        if not m:
            continue
        key, value = m[1], m[2]
        if key in ("output", "absent", "proof"):
            h[key].append(value)
        elif key == "seeds":
            h["seeds"] = [int(x) for x in value.split()]
        else:
            h[key] = value.strip()
    assert "celf" in h and "expect" in h, f"{path.name}: a '% celf:' and a '% expect:' line are required"
    assert ("construct" in h) != ("behaviour" in h), f"{path.name}: '% construct:' or '% behaviour:'"
    return h


def test_suite_covers_issue_13():
    names = {p.stem for p in CASES}
    assert len(CASES) >= 25
    for needed in ("lex_identifiers", "directive_sees_prefix", "query_attempts_any", "query_e_above_l",
                   "query_ignored", "exists_function_in_context", "typing_linear_lambda",
                   "typing_bound_application", "mode_implicit_and_empty", "mode_error", "pattern_exists",
                   "pattern_pi", "lambda_annotated", "proof_term_definition", "proof_term_patterns",
                   "proof_term_linearity", "linear_premise_backward", "linear_premise_consumes",
                   "logic_variable_in_context", "logic_variable_in_rule_head", "logic_variable_accumulator",
                   "query_e_equals_l", "query_look_one_more", "query_bounds_checked_in_order",
                   "exec_context_shape", "exec_failed", "trace_contexts", "solution_term_printed"):
        assert needed in names, needed


@pytest.mark.parametrize("path", CASES, ids=[p.stem for p in CASES])
def test_celf_answer(path, capsys):
    h = header(path)
    m = EXPECT.match(h["expect"])
    assert m, f"{path.name}: bad '% expect:' line"
    kind = m[1]
    for seed in h["seeds"]:
        with pytest.raises(SystemExit) as info:
            main(["clf", str(path), "--seed", str(seed)])
        out, err = capsys.readouterr()
        code = info.value.code or 0
        assert "Traceback" not in out + err and "internal error" not in err, err
        for line in h["output"]:
            assert line in out.splitlines(), (seed, line, out)
        for text in h["absent"]:
            assert text not in out, (seed, text, out)
        if h["proof"]:
            with pytest.raises(SystemExit):
                main(["clf", str(path), "--seed", str(seed), "--proof"])
            pout, _perr = capsys.readouterr()
            for line in h["proof"]:
                assert line in pout.splitlines(), (seed, line, pout)
        if kind == "ok":
            assert code == 0, (seed, out, err)
            continue
        assert code == 2, (seed, out, err)
        line, col, fragment = int(m[2]), int(m[3]), m[4]
        first = err.strip().splitlines()[0]
        assert first.startswith(f"error: {path}:{line}:{col}: "), (seed, first)
        assert fragment in err, (seed, err)
        if kind != "unsupported":
            assert kind in err, (seed, err)  # Celf's category is named


@pytest.mark.parametrize("path", [p for p in CASES if "expect: ok" not in p.read_text()],
                         ids=lambda p: p.stem)
def test_library_error_class(path):
    """The library raises a located RoarError whose class gives Celf's category."""
    h = header(path)
    kind = EXPECT.match(h["expect"])[1]
    with pytest.raises(RoarError) as info:
        with_big_stack(run_file, path, emit=lambda line: None)
    exc = info.value
    assert exc.pos is not None and exc.pos.line >= 1
    if kind == "unsupported":
        assert isinstance(exc, UnsupportedError)
    else:
        assert celf_category(exc) == kind


# -- the conformance table of docs/clf.md -------------------------------------------

DOCS = ROOT / "docs" / "clf.md"


def docs_table() -> list[tuple[str, str, list[str]]]:
    text = DOCS.read_text(encoding="utf-8")
    section = text.split("## Celf conformance", 1)[1]
    rows = []
    for line in section.splitlines():
        if not line.startswith("|") or line.startswith("|---") or line.startswith("| construct or behaviour"):
            continue
        cells = [c.strip() for c in re.split(r"(?<!\\)\|", line.strip().strip("|"))]
        construct, supported, examples = cells[0], cells[1], cells[2]
        rows.append((construct, supported, [e.strip() for e in examples.split(",") if e.strip()]))
    return rows


def test_docs_table_is_true(capsys):
    rows = docs_table()
    assert len(rows) >= 15
    named = set()
    for construct, supported, examples in rows:
        assert supported in ("yes", "no"), construct
        assert examples, construct
        for name in examples:
            path = HERE / name
            assert path.exists(), (construct, name)
            named.add(path)
            h = header(path)
            # a "no" row is a recorded deviation from Celf's answer, a "yes" row none
            assert ("deviation" in h) == (supported == "no"), (construct, name)
            test_celf_answer(path, capsys)  # the example gives the answer its header states
    # every program of the suite is in the table
    assert named == set(CASES), sorted(p.name for p in set(CASES) - named)
