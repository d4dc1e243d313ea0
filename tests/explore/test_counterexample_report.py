"""Counterexamples as an engineer reads them (issue 17, items 3 and 4): the per-agent final
state and wait-for cycle, the same data in --json, the sequence chart and the DOT graph."""

from __future__ import annotations

import json
import re

import pytest

from roar_formal.cli import main
from roar_formal.errors import RoarError
from roar_formal.verify.check import run_job
from roar_formal.verify.jobs import load_job
from roar_formal.verify.pictures import render_chart, sequence_chart, state_graph_dot
from roar_formal.verify.report import counterexample_report

from repo import ROOT
_RESULTS: dict = {}


def result(name: str):
    if name not in _RESULTS:
        _RESULTS[name] = run_job(load_job(ROOT / "checker" / name))
    return _RESULTS[name]


def cli(monkeypatch, capsys, *args):
    monkeypatch.chdir(ROOT)
    with pytest.raises(SystemExit) as e:
        main([str(a) for a in args])
    out = capsys.readouterr()
    return e.value.code, out.out, out.err


# ------------------------------------------------------------------ item 3: the report


def test_deadlock_report_names_blocked_activities_and_the_wait_for_cycle():
    rep = counterexample_report(result("mutual_make.toml"), "deadlock")
    assert rep["shape"] == "path" and len(rep["steps"]) == 27
    assert rep["requests"]["R1"] == {"agent": "door", "constraint": "door::open == true"}
    final = rep["final"]
    assert set(final) == {"arm", "door"}
    assert final["arm"]["variables"] == {"parked": "false", "started": "false"}
    assert {r["request"]: r["state"] for r in final["door"]["requests"]} == {"R1": "running"}
    dl = rep["deadlock"]
    assert dl["cycle"] == ["arm", "door"]
    blocked = {(b["agent"], b["recipe"]): b for b in dl["blocked"]}
    assert blocked[("door", "swing")]["on"] == "R2" and blocked[("door", "swing")]["waits_for"] == ["arm"]
    assert blocked[("arm", "through_door")]["on"] == "R1"
    assert blocked[("arm", "fold")]["status"] == "blocked in a wait"
    assert {(e["from"], e["to"], e["request"]) for e in dl["wait_for"]} >= {("arm", "door", "R1"),
                                                                           ("door", "arm", "R2")}


def test_steps_carry_variable_changes_old_to_new():
    rep = counterexample_report(result("retry_forever.toml"), "livelock")
    assert rep["shape"] == "lasso" and rep["deadlock"] is None
    assert any(s["loop"] for s in rep["steps"])
    # every change is a real change, with the agent that owns the variable
    for s in rep["steps"]:
        for ch in s["changes"]:
            assert ch["old"] != ch["new"] and ch["var"].startswith(ch["agent"] + "::")


def test_cli_prints_the_final_state_per_agent_and_the_cycle(monkeypatch, capsys):
    code, out, _ = cli(monkeypatch, capsys, "check", "checker/mutual_make.toml", "--no-traces")
    assert code == 0
    lines = out.splitlines()
    i = lines.index("    final state:")
    table = lines[i + 1:lines.index(next(x for x in lines if x.startswith("    wait-for cycle:")))]
    assert table[0].split()[:2] == ["arm", "variables:"]
    assert any(x.split()[:2] == ["door", "variables:"] for x in table)
    assert "    wait-for cycle: arm -> door -> arm" in lines
    assert any(x.startswith("      door waits for arm: open_door.swing waits for R2") for x in lines)


def test_json_carries_the_same_report(monkeypatch, capsys):
    code, out, _ = cli(monkeypatch, capsys, "check", "checker/mutual_make.toml", "--no-traces", "--json")
    assert code == 0
    rep = json.loads(out)[0]["verdicts"]["deadlock"]["counterexample"]["report"]
    assert rep["deadlock"]["cycle"] == ["arm", "door"]
    assert rep == json.loads(json.dumps(counterexample_report(result("mutual_make.toml"), "deadlock")))


# ------------------------------------------------------------------ item 4: pictures


def test_chart_has_one_lifeline_per_agent_and_marks_the_cycle():
    res = result("mutual_make.toml")
    fig, ax, art = sequence_chart(res, "deadlock")
    assert set(art["lifelines"]) == {"arm", "door"} and len(ax.lines) == 2
    assert {t.get_text() for t in art["heads"].values()} == {"arm", "door"}
    sent = {(a, b) for a, b, _label, _ann in art["arrows"]}
    assert sent == {("arm", "door"), ("door", "arm")}
    assert any("make R2: arm::parked == true" in label for *_x, label, _ann in art["arrows"])
    assert {(a, b) for a, b, _ann in art["cycle"]} == {("arm", "door"), ("door", "arm")}
    assert all(ann.arrow_patch.get_edgecolor()[0] > 0.7 for _a, _b, ann in art["cycle"])   # red
    assert art["cycle_label"].get_text() == "deadlock: wait-for cycle arm → door → arm"
    notes = [t.get_text() for t in art["notes"]]
    assert any(n.startswith("blocked: open_door.swing") for n in notes)


def test_chart_files_are_valid_and_deterministic(monkeypatch, capsys, tmp_path):
    res = result("mutual_make.toml")
    png = render_chart(res, "deadlock", "png")
    assert png[:8] == b"\x89PNG\r\n\x1a\n" and png == render_chart(res, "deadlock", "png")
    svg = render_chart(res, "deadlock", "svg")
    assert svg == render_chart(res, "deadlock", "svg")
    assert b"<svg" in svg and b"Date" not in svg and b"dc:date" not in svg
    code, out, _ = cli(monkeypatch, capsys, "check", "checker/mutual_make.toml", "--no-traces",
                       "--png", tmp_path / "png", "--svg", tmp_path / "svg", "--dot", tmp_path / "dot")
    assert code == 0
    written = sorted(p.relative_to(tmp_path).as_posix() for p in tmp_path.rglob("*") if p.is_file())
    assert written == ["dot/mutual-make__faulty_.deadlock.dot", "png/mutual-make__faulty_.deadlock.png",
                       "svg/mutual-make__faulty_.deadlock.svg"]
    assert (tmp_path / "png" / "mutual-make__faulty_.deadlock.png").read_bytes() == png
    assert f"picture: {tmp_path / 'png' / 'mutual-make__faulty_.deadlock.png'}" in out.replace("\n", "")


_NODE = re.compile(r'^  s(\d+) \[(.*)\];$')
_EDGE = re.compile(r'^  s(\d+) -> s(\d+) \[(.*)\];$')


def test_dot_parses_and_highlights_the_counterexample_path():
    res = result("mutual_make.toml")
    text = state_graph_dot(res, "deadlock")
    lines = text.splitlines()
    assert lines[0].startswith("digraph ") and lines[0].endswith("{") and lines[-1] == "}"
    nodes = [m for m in map(_NODE.match, lines) if m]
    edges = [m for m in map(_EDGE.match, lines) if m]
    body = [x for x in lines[1:-1] if not x.startswith("  rankdir") and not x.startswith(("  node [", "  edge ["))]
    assert len(body) == len(nodes) + len(edges)   # every other line is a node or an edge
    assert len(nodes) == res.graph.n_states and len(edges) == res.graph.n_edges
    for m in edges:   # balanced quotes: every attribute list parses as key=value pairs
        assert re.fullmatch(r'(\w+=("([^"\\]|\\.)*"|[\w.]+)(, )?)+', m.group(3)), m.group(3)
    cx = res.verdicts["deadlock"].counterexample
    red = {(int(m.group(1)), int(m.group(2))) for m in edges if "penwidth=2.5" in m.group(3)}
    g = res.graph
    assert red == {(int(g.src[e]), int(g.dst[e])) for e in cx.prefix} and len(red) == 27
    final = next(m for m in nodes if int(m.group(1)) == cx.final_state)
    assert "fillcolor" in final.group(2)


def test_dot_refuses_a_large_graph_and_bad_output_folders_are_located(monkeypatch, capsys, tmp_path):
    res = result("mutual_make.toml")
    with pytest.raises(RoarError, match="--dot draws at most 10 "):
        state_graph_dot(res, "deadlock", max_states=10)
    afile = tmp_path / "afile"
    afile.write_text("keep")
    code, _out, err = cli(monkeypatch, capsys, "check", "checker/mutual_make.toml", "--no-traces", "--png", afile)
    assert code == 2 and "--png" in err and "not a folder" in err and "Traceback" not in err
    assert afile.read_text() == "keep"


SELF_WAIT = """
gimbal = ability {
  context = { { } { int pitch = 10; bool stable = false; } { } }
  tasks = { level = task { post = { {stable == true} } recipes = { servo = recipe { body = {
    wait(pitch <= 0);
    set stable true;
  } } } } }
}
camera = ability {
  context = { { } { bool shot = false; } { } }
  tasks = { shoot = task { post = { {shot == true} } recipes = { steady = recipe { body = {
    make(gimbal::stable == true);
    set shot true;
  } } } } }
}
"""


def deadlock_check(tmp_path, monkeypatch, capsys, spec_text: str, request: str) -> tuple[int, str]:
    """``roar-verify check SPEC -r REQUEST --property deadlock``: its exit status and output, on one line."""
    spec = tmp_path / "spec.roar"
    spec.write_text(spec_text, encoding="utf-8")
    code, out, _err = cli(monkeypatch, capsys, "check", spec, "-r", request, "--property", "deadlock",
                          "--traces", tmp_path)
    return code, " ".join(out.split())


def test_a_wait_on_the_agents_own_variables_is_a_cycle_of_one_said_so(tmp_path, monkeypatch, capsys):
    """The gimbal waits for its own pitch, which nothing changes: the wait-for graph has the
    gimbal waiting for itself, and the report says what that means (it said "gimbal waits for
    gimbal", and the message for no cycle named this very case)."""
    code, text = deadlock_check(tmp_path, monkeypatch, capsys, SELF_WAIT, "camera::shot == true")
    assert code == 1 and "wait-for cycle: gimbal -> gimbal" in text
    assert "gimbal waits for its own variables: level.servo waits in wait(pitch <= 0)" in text
    assert "waits for gimbal:" not in text


ABORT_THEN_WAIT = """
mission = ability {
  context = { { } { bool done = false; } { } }
  tasks = {
    go = task {
      post = { {done == true} }
      recipes = {
        r = recipe {
          body = {
            let h ensure(camera::located == true);
            abort h;
            wait(camera::located == true);
            set done true;
          }
        }
      }
    }
  }
}
camera = ability {
  context = { { } { bool located = false; } { } }
  tasks = {
    locate = task {
      post = { {located == true} }
      recipes = { snap = recipe { body = { set located true; } } }
    }
  }
}
"""


def test_a_wait_on_an_idle_agent_names_it(tmp_path, monkeypatch, capsys):
    """The mission aborts its ensure before the camera acts, then waits for what it asked: a
    deadlock with no cycle, the mission waiting for a camera that has nothing to run (it said
    "the blocked activities wait for no agent")."""
    code, text = deadlock_check(tmp_path, monkeypatch, capsys, ABORT_THEN_WAIT, "mission::done == true")
    assert code == 1 and "deadlock: violated" in text
    assert "wait for agents that have nothing left to do" in text and "wait for no agent" not in text
    assert "mission waits for camera: go.r waits in wait(camera::located == true)" in text
    assert "camera runs nothing that could change it" in text
