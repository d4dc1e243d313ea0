"""The pytest plugin, run with pytester: the docs' worked example as documented, fixtures, budgets, traces."""

import re
import shutil
from importlib.metadata import entry_points

import pytest
from hypothesis import settings

from roar_formal import load_spec
from roar_formal.testing import RoarAssertionError, assert_no_livelock
from roar_formal.trace.format import read_trace

QUIET = ("-p", "no:cacheprovider", "-W", "ignore::DeprecationWarning")


@pytest.fixture
def keep_hypothesis_profile():
    """The example's conftest loads a hypothesis profile; an in-process run must not leave it loaded."""
    name = getattr(settings, "_current_profile", None) or "default"
    yield
    settings.load_profile(name)


def copy(src, pytester):
    for f in src.iterdir():
        if f.is_file():
            shutil.copy(f, pytester.path / f.name)


# ------------------------------------------------------------------ the worked example


def test_the_plugin_is_registered_through_its_entry_point():
    eps = {ep.name: ep.value for ep in entry_points(group="pytest11")}
    assert eps.get("roar_formal") == "roar_formal.testing.plugin"


def test_the_files_the_docs_quote_are_the_example_files(root):
    """``<!-- file: P -->``: the block is file P; ``<!-- part of: P -->``: its lines are lines of P, in order."""
    text = (root / "docs" / "testing.md").read_text(encoding="utf-8")
    quoted = re.findall(r"<!-- (file|part of): (\S+) -->\n```[a-z]*\n(.*?)```", text, re.S)
    assert len(quoted) >= 5
    for kind, path, block in quoted:
        content = (root / path).read_text(encoding="utf-8")
        if kind == "file":
            assert block == content, path
        else:
            lines = [x.strip() for x in content.splitlines()]
            i = 0
            for want in block.splitlines():
                while i < len(lines) and lines[i] != want.strip():
                    i += 1
                assert i < len(lines), f"{path}: docs/testing.md quotes a line it does not have: {want!r}"
                i += 1


def test_the_two_copies_of_the_example_test_are_the_same_test(examples):
    for name in ("test_pick.py", "conftest.py"):
        assert (examples / "pick" / name).read_text() == (examples / "pick_fixed" / name).read_text()
    buggy = (examples / "pick" / "pick.roar").read_text()
    fixed = (examples / "pick_fixed" / "pick.roar").read_text()
    assert "end = { set busy false; }" in fixed and "end =" not in buggy


def test_the_worked_example_fails_shrinks_and_prints_its_counterexample(pytester, examples, docs_shows,
                                                                        keep_hypothesis_profile):
    copy(examples / "pick", pytester)
    result = pytester.runpytest(*QUIET)
    result.assert_outcomes(failed=1, passed=1)
    out = result.stdout.str()
    assert "plugins:" in out and "roar-formal" in out                # loaded from the entry point
    assert "faults=['close_jaws:1'],\nE           seed=0," in out     # the shrunk example
    docs_shows("pick", out)
    trace = re.search(r"trace: (\S+pick\.run\.jsonl)", out).group(1)
    header, steps = read_trace(trace)
    assert header["outcome"] == "failure" and header["faults"] == ["close_jaws:1"] and len(steps) == 41


def test_the_same_test_passes_on_the_fixed_spec(pytester, examples, docs_shows, keep_hypothesis_profile):
    copy(examples / "pick_fixed", pytester)
    result = pytester.runpytest(*QUIET)
    result.assert_outcomes(passed=2)
    docs_shows("pick_fixed", result.stdout.str())


def test_the_livelock_excerpt_is_what_the_helper_says(examples, docs_shows):
    with pytest.raises(RoarAssertionError) as e:
        assert_no_livelock(load_spec(examples / "pick_fixed" / "pick.roar"), "cell::lifted == true")
    docs_shows("pick_livelock", "roar_formal.testing.assertions.RoarAssertionError: " + str(e.value))


# ------------------------------------------------------------------ fixtures, marker, options


PLUGIN_TESTS = '''
import pytest
from roar_formal.testing import assert_no_deadlock

def test_loads_relative_to_the_test_file(roar_load, roar_budget, roar_traces):
    spec = roar_load("specs/mutual_make.roar")
    assert spec.agents == ["arm", "door"] and roar_load("specs/mutual_make.roar") is spec
    assert roar_budget.max_states == BUDGET_STATES
    assert roar_traces.is_dir()

def test_deadlock(roar_load):
    assert_no_deadlock(roar_load("specs/mutual_make.roar"), "arm::started == true")

@pytest.mark.roar_budget(max_states=5)
def test_small_budget(roar_load, roar_budget):
    assert roar_budget.max_states == 5
    assert_no_deadlock(roar_load("ok.clf"))

@pytest.mark.roar_budget(max_states=100_000)
def test_large_budget(roar_load):
    assert_no_deadlock(roar_load("ok.clf"))

@pytest.mark.roar_budget(max_states="many")
def test_bad_marker():
    pass
'''


@pytest.fixture
def plugin_suite(pytester, models):
    (pytester.path / "specs").mkdir()
    shutil.copy(models / "faulty" / "mutual_make.roar", pytester.path / "specs")
    shutil.copy(models / "philosophers" / "ok.clf", pytester.path)
    return pytester


def test_fixtures_marker_and_the_deadlock_message(plugin_suite, run_cli, tmp_path):
    plugin_suite.makepyfile(test_plugin_suite=PLUGIN_TESTS.replace("BUDGET_STATES", "200_000"))
    traces = tmp_path / "traces"
    result = plugin_suite.runpytest(*QUIET, f"--roar-traces={traces}")
    result.assert_outcomes(passed=2, failed=3)
    result.stdout.fnmatch_lines(["*roar_budget(max_states='many'): expected a whole number above 0"])
    out = result.stdout.str()
    # the deadlock: its counterexample, as `check` prints it, and where its trace is
    result.stdout.fnmatch_lines([
        "E*RoarAssertionError: deadlock violated on *specs/mutual_make.roar, request arm::started == true",
        "E*deadlock: violated — deadlock reachable in 27 steps (1 deadlock state among 28 states)",
        "E*18. door         make R2 to arm: arm::parked == true",
        f"E*trace: {traces}/mutual_make.deadlock.jsonl  (roar-verify replay *",
    ])
    assert "test_deadlock" in out and "FAILED test_plugin_suite.py::test_small_budget" in out
    result.stdout.fnmatch_lines(["E*deadlock not decided on *ok.clf: no deadlock in * states; search "
                                 "incomplete (state budget of 5 reached)"])
    code, out, err = run_cli("replay", traces / "mutual_make.deadlock.jsonl", "--model",
                             plugin_suite.path / "specs" / "mutual_make.roar")
    assert code == 0 and "replayed 27 steps" in out, err


def test_the_budget_option_is_the_default_and_a_marker_wins(plugin_suite):
    plugin_suite.makepyfile(test_plugin_suite=PLUGIN_TESTS.replace("BUDGET_STATES", "7"))
    result = plugin_suite.runpytest(*QUIET, "--roar-budget", "states=7,seconds=30", "-k", "not deadlock and not bad")
    result.assert_outcomes(passed=2, failed=1)        # the small budget's test fails, the marker's 100,000 wins
    result = plugin_suite.runpytest(*QUIET, "--roar-budget", "states=x")
    assert result.ret == pytest.ExitCode.USAGE_ERROR
    result.stderr.fnmatch_lines(["*--roar-budget 'states=x': states must be a number, not 'x'"])
    result = plugin_suite.runpytest(*QUIET, "--roar-budget", "rounds=3")
    result.stderr.fnmatch_lines(["*unknown key 'rounds'; expected states, seconds or memory"])


def test_parse_budget():
    from roar_formal.testing.plugin import parse_budget
    assert parse_budget("50000") == {"max_states": 50000}
    assert parse_budget("states=1_000, seconds=2.5 memory=512") == {"max_states": 1000, "max_seconds": 2.5,
                                                                  "max_memory_mb": 512}
    with pytest.raises(ValueError, match="above 0"):
        parse_budget("seconds=0")


def test_a_mistake_in_a_test_is_shown_without_the_librarys_frames(pytester, examples):
    """A RoarError (here a request with '=' for '==') is shown from the test's own code: the
    located message, not dozens of lines of roar_formal internals."""
    shutil.copytree(examples / "pick_fixed", pytester.path / "pick")
    pytester.makepyfile(test_mistake='''
from roar_formal import load_spec

def test_wrong_request():
    load_spec("pick/pick.roar").run("cell::lifted = true")
''')
    result = pytester.runpytest(*QUIET, "test_mistake.py")
    result.assert_outcomes(failed=1)
    out = result.stdout.str()
    # at the test's own line, the column inside the request's quotes
    line = 'load_spec("pick/pick.roar").run("cell::lifted = true")'
    col = ('    ' + line).index("cell::lifted") + len("cell::lifted ") + 1
    assert f"test_mistake.py:4:{col}: unexpected '='" in out
    assert "roar_formal/roar/parser.py" not in out and "roar_formal/testing/api.py" not in out
    assert 'load_spec("pick/pick.roar").run("cell::lifted = true")' in out
