"""The commands the docs mark as checked run, and print what the docs show.

A fenced ``sh`` block in README.md or docs/*.md preceded by ``<!-- checked -->`` (or
``<!-- checked: exit N -->`` for a command that exits N) is run: each of its lines is a
``roar-verify`` command, run in-process from a folder that sees the repository's
``models/``, ``checker/`` and ``properties/`` (files the commands write land there, not in
the repository). The next fenced block without a language (or ``text``) after it is the
output the docs show: each of its lines must appear in the output, in order, as the start of
an output line (surrounding blanks ignored). In a shown line ``...`` stands for any text and
a time such as ``0.50 s`` for any time; a line that is only ``...`` is skipped.
"""

from __future__ import annotations

import re
import shlex

import pytest

from repo import ROOT
DOCS = [ROOT / "README.md", *sorted((ROOT / "docs").glob("*.md"))]
_BLOCK = re.compile(r"<!-- checked(?::\s*exit\s+(\d+))?\s*-->\n```sh\n(.*?)```\n(.*?)```(?:text)?\n(.*?)```", re.S)


def checked_blocks() -> list:
    out = []
    for doc in DOCS:
        text = doc.read_text(encoding="utf-8")
        for m in _BLOCK.finditer(text):
            between = m.group(3)
            assert "```" not in between, f"{doc.name}: a checked command's output block must be the next fenced block"
            line = text[: m.start()].count("\n") + 1
            out.append(pytest.param(int(m.group(1) or 0), m.group(2), m.group(4),
                                    id=f"{doc.relative_to(ROOT)}:{line}"))
    return out


def _pattern(shown: str) -> re.Pattern:
    parts = re.split(r"(\.\.\.|…|\d+\.\d+ s\b)", shown.strip())
    rx = "".join(".*" if p in ("...", "…") else r"\d+\.\d+ s" if re.fullmatch(r"\d+\.\d+ s", p) else re.escape(p)
                 for p in parts)
    return re.compile(rx)


def shows(output: str, shown: str) -> None:
    """Every shown line is the start of an output line, in order."""
    lines = [x.strip() for x in output.splitlines()]
    i = 0
    for want in shown.splitlines():
        if not want.strip() or want.strip() in ("...", "…"):
            continue
        rx = _pattern(want)
        while i < len(lines) and not rx.match(lines[i]):
            i += 1
        assert i < len(lines), f"the docs show a line the command does not print (in this order): {want.strip()!r}" \
                               f"\n--- output:\n{output}"
        i += 1


def test_the_docs_mark_commands_as_checked():
    names = {p.id.split(":")[0] for p in checked_blocks()}
    assert "README.md" in names and "docs/checking.md" in names
    assert len(checked_blocks()) >= 3


@pytest.mark.parametrize("status,commands,shown", checked_blocks())
def test_a_checked_command_prints_what_the_docs_show(roar_cli, monkeypatch, tmp_path, status, commands, shown):
    for d in ("models", "checker", "properties"):
        (tmp_path / d).symlink_to(ROOT / d)
    monkeypatch.chdir(tmp_path)
    output = ""
    code = 0
    for line in commands.splitlines():
        line = line.split(" # ")[0].strip()
        if not line:
            continue
        argv = shlex.split(line)
        assert argv[0] == "roar-verify", f"a checked block runs roar-verify commands only: {line}"
        code, out, err = roar_cli(*argv[1:])
        output += out + err
    assert code == status, f"exit {code}, the docs say {status}\n{output}"
    shows(output, shown)


def test_the_comparison_fails_on_a_line_the_output_lacks_or_misorders():
    out = "ok job  (5 states, 0.12 s)\n  deadlock: violated\n  final state: a; b; c\n"
    shows(out, "ok job  (5 states, 9.99 s)\n  final state: a; ...; c\n")
    with pytest.raises(AssertionError):
        shows(out, "  deadlock: holds\n")
    with pytest.raises(AssertionError):
        shows(out, "  final state: a; b; c\n  deadlock: violated\n")
