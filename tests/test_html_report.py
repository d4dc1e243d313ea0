"""``roar-verify check --html DIR``: the report's files, its content, and the page in a real headless browser."""

from __future__ import annotations

import io
import json
import os
import re
import shutil

import pytest

from repo import ROOT
JOB = ROOT / "checker" / "mutual_make.toml"
CHROMIUM = "/usr/bin/chromium"
CHROMEDRIVER = "/usr/bin/chromedriver"


@pytest.fixture(scope="module")
def report(tmp_path_factory):
    """One run of ``check --html`` on checker/mutual_make.toml (a deadlock, as expected)."""
    import contextlib

    from roar_formal.cli import main
    base = tmp_path_factory.mktemp("html")
    out, err = io.StringIO(), io.StringIO()
    env = {"NO_COLOR": "1", "COLUMNS": "200"}
    old = {k: os.environ.get(k) for k in env}
    os.environ.update(env)
    code = 0
    try:
        with contextlib.redirect_stdout(out), contextlib.redirect_stderr(err):
            try:
                main(["check", str(JOB), "--html", str(base / "report"), "--traces", str(base / "traces")])
            except SystemExit as exc:
                code = exc.code
    finally:
        for k, v in old.items():
            if v is None:
                os.environ.pop(k, None)
            else:
                os.environ[k] = v
    out, err = out.getvalue(), err.getvalue()
    return code, out, err, base / "report", base / "traces"


def test_the_report_folder_holds_the_page_the_chart_the_trace_and_the_json(report):
    code, out, err, folder, traces = report
    assert code == 0, err
    assert f"HTML report: {folder / 'index.html'}" in out
    page = (folder / "index.html").read_text(encoding="utf-8")
    charts = sorted((folder / "charts").glob("*.svg"))
    assert [c.name for c in charts] == ["0-mutual-make__faulty_.deadlock.svg"]
    assert charts[0].read_bytes().lstrip().startswith((b"<?xml", b"<svg"))
    # the trace is copied into the report and linked, byte for byte the one --traces saved
    copied = folder / "traces" / "0-mutual-make__faulty_.deadlock.jsonl"
    assert copied.read_bytes() == (traces / "mutual-make__faulty_.deadlock.jsonl").read_bytes()
    assert 'href="traces/0-mutual-make__faulty_.deadlock.jsonl"' in page
    assert 'src="charts/0-mutual-make__faulty_.deadlock.svg"' in page
    # the counterexample in ROAR terms: the wait-for cycle, the per-agent final state, a variable change
    assert "wait-for cycle: arm -&gt; door -&gt; arm" in page
    assert "door waits for arm: open_door.swing waits for R2 (arm::parked == true)" in page
    assert "parked = false, started = false" in page
    assert "make R1 to door: door::open == true" in page
    # report.json is what --json prints: the same verdicts and the same counterexample report
    doc = json.loads((folder / "report.json").read_text(encoding="utf-8"))
    assert doc[0]["job"] == "mutual-make (faulty)"
    assert doc[0]["verdicts"]["deadlock"]["status"] == "violated"
    assert doc[0]["verdicts"]["deadlock"]["counterexample"]["report"]["deadlock"]["cycle"] == ["arm", "door"]
    assert doc[0]["verdicts"]["livelock"]["status"] == "holds"
    # the steps with no ROAR event are left out, as in the terminal, and counted (the JSON has them)
    steps = doc[0]["verdicts"]["deadlock"]["counterexample"]["report"]["steps"]
    silent = [s for s in steps if not s["changes"] and all(e["kind"] == "write" for e in s["events"])]
    rows = re.findall(r'<tr><td class="n">(\d+)</td>', page)
    assert silent and len(rows) == len(steps) - len(silent)
    assert {int(r) for r in rows}.isdisjoint(s["step"] for s in silent)
    assert 'class="internal"' not in page
    assert f"{len(silent)} engine steps with no ROAR event are not shown" in page
    # no temporary file of the atomic writer is left behind (the one hidden file: the report's list of its files)
    assert [p.name for p in folder.rglob(".*") if p.is_file()] == [".roar-verify-report"]


def test_the_page_names_each_verdict_in_the_summary_and_in_its_section(report):
    _, _, _, folder, _ = report
    page = (folder / "index.html").read_text(encoding="utf-8")
    summary = re.search(r'<table id="summary">.*?</table>', page, re.S).group(0)
    assert "mutual-make (faulty)" in summary and 'class="violated">violated' in summary
    assert 'class="holds">holds' in summary and "as expected" in summary
    assert 'data-property="deadlock" data-status="violated"' in page
    assert 'data-property="livelock" data-status="holds"' in page


def test_an_html_folder_that_cannot_be_written_is_refused_before_any_work(roar_cli, tmp_path):
    afile = tmp_path / "afile"
    afile.write_text("x")
    code, out, err = roar_cli("check", JOB, "--html", afile / "report", "--no-traces")
    assert code == 2
    assert f"--html {afile / 'report'}: {afile} is not a folder" in err
    assert "states" not in out   # no job ran


def test_a_folder_of_the_users_files_is_refused_and_an_earlier_reports_stale_files_go(roar_cli, tmp_path):
    # a folder of the user's own files: refused before any work, nothing of it touched
    mine = tmp_path / "mine"
    mine.mkdir()
    (mine / "index.html").write_text("MY NOTES")
    code, out, err = roar_cli("check", JOB, "--html", mine, "--no-traces")
    assert code == 2 and f"--html {mine}: the folder holds files no report of roar-verify wrote (index.html)" in err
    assert "states" not in out and (mine / "index.html").read_text() == "MY NOTES"
    # a report with a counterexample, then one without into the same folder: the first one's chart
    # and trace, which the second does not link, are removed; the second one's files are listed
    rep = tmp_path / "rep"
    code, _out, _err = roar_cli("check", JOB, "--html", rep, "--traces", tmp_path / "traces")
    assert code == 0
    first = {p.relative_to(rep).as_posix() for p in rep.rglob("*") if p.is_file()}
    assert any(x.startswith("charts/") for x in first) and any(x.startswith("traces/") for x in first)
    fixed = ROOT / "checker" / "mutual_make_fixed.toml"
    code, _out, _err = roar_cli("check", fixed, "--html", rep, "--no-traces")
    assert code == 0
    second = {p.relative_to(rep).as_posix() for p in rep.rglob("*") if p.is_file()}
    assert second == {"index.html", "style.css", "report.json", ".roar-verify-report"}
    assert set((rep / ".roar-verify-report").read_text().split()) == second - {".roar-verify-report"}
    # a file of the user's put into a report folder: refused too
    (rep / "notes.txt").write_text("mine")
    code, _out, err = roar_cli("check", fixed, "--html", rep, "--no-traces")
    assert code == 2 and "holds files the earlier report there did not write (notes.txt)" in err
    assert (rep / "notes.txt").read_text() == "mine"


def _browser():
    for tool in (CHROMIUM, CHROMEDRIVER):
        if not (os.path.exists(tool) and os.access(tool, os.X_OK)):
            pytest.fail(f"{tool} is missing: the HTML report is checked in a real headless browser; install it "
                        "with `apt-get install -y chromium chromium-driver` (.ci/run does)")
    from selenium import webdriver
    from selenium.webdriver.chrome.service import Service
    opts = webdriver.ChromeOptions()
    opts.binary_location = CHROMIUM
    for a in ("--headless=new", "--no-sandbox", "--disable-gpu", "--disable-dev-shm-usage", "--window-size=1280,1600",
              "--allow-file-access-from-files"):
        opts.add_argument(a)
    return webdriver.Chrome(service=Service(CHROMEDRIVER), options=opts)


def test_the_report_renders_in_a_headless_browser(report, tmp_path):
    from selenium.webdriver.common.by import By

    _, _, _, folder, _ = report
    shutil.copytree(folder, tmp_path / "site")   # a copy: the report moves as a whole (relative links)
    driver = _browser()
    try:
        driver.get((tmp_path / "site" / "index.html").as_uri())
        assert driver.title == "roar-verify check"
        body = driver.find_element(By.TAG_NAME, "body").text
        assert "mutual-make (faulty)" in body
        assert "deadlock: violated" in body and "livelock: holds" in body
        assert "wait-for cycle: arm -> door -> arm" in body
        img = driver.find_element(By.CSS_SELECTOR, "img.chart")
        width, height, complete = driver.execute_script(
            "const i = arguments[0]; return [i.naturalWidth, i.naturalHeight, i.complete];", img)
        assert complete and width > 100 and height > 100, (width, height)
        assert img.size["width"] > 100 and img.size["height"] > 100
        link = driver.find_element(By.CSS_SELECTOR, "a.trace")
        assert link.get_attribute("href").endswith("/traces/0-mutual-make__faulty_.deadlock.jsonl")
        shot = driver.get_screenshot_as_png()
    finally:
        driver.quit()
    (tmp_path / "screenshot.png").write_bytes(shot)
    import matplotlib.image as mpimg
    import numpy as np
    pixels = mpimg.imread(io.BytesIO(shot), format="png")[..., :3]
    assert pixels.shape[0] > 500 and pixels.shape[1] > 500
    not_white = (pixels < 0.95).any(axis=2).mean()
    assert 0.01 < not_white < 0.9, not_white   # text, tables and the chart: neither blank nor one colour
    assert np.unique(pixels.reshape(-1, 3), axis=0).shape[0] > 20   # many colours: a rendered page
