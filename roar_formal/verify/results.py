"""A job's result, and its counterexamples as steps, ROAR events and trace files."""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path
from typing import Optional

from ..clf.program import Program
from ..trace.format import write_trace
from ..explore.graph import StateGraph
from ..explore.search import path_steps
from .claims import trace_claim
from .jobs import Job
from ..explore.properties import Verdict


@dataclass
class JobResult:
    job: Job
    verdicts: dict[str, Verdict]
    graph: StateGraph
    backend: str
    seconds: float
    memory_mb: float
    mismatches: list[str] = field(default_factory=list)
    program: Optional[Program] = None
    reduction: str = "off"  # 'on', 'off' or 'not used by the ground backend'
    fingerprint: Optional[dict] = None  # of the sources explored (trace/fingerprint.py)
    symmetry: str = ""  # symmetry reduction: what it found (the job turned it on), else ""

    @property
    def unexpected(self) -> list[str]:
        """What makes the job fail: verdicts other than the expected ones, and violations of
        properties the job expects nothing of (a violation is an error unless [expect] says so)."""
        out = list(self.mismatches)
        for p, v in self.verdicts.items():
            if v.status == "holds" and v.details.get("vacuous"):
                out.append(f"{p}: holds only vacuously ({v.details['vacuous']}): it checked nothing; if the trigger "
                           "is meant to be unreachable, say so with an invariant (never = [...])")
            if p not in self.job.expect and v.status == "violated":
                if "command line" in self.job.props.sources:   # (no job file: nothing can be expected)
                    out.append(f"{p}: violated: a check from the command line expects every property to hold "
                               f"(a job file's [expect] {p} = \"violated\" says a violation is intended)")
                else:
                    out.append(f"{p}: violated, and the job expects nothing of it: a violation is an error "
                               f"(write [expect] {p} = \"violated\" if it is intended)")
        return out

    @property
    def ok(self) -> bool:
        return not self.unexpected

    @property
    def incomplete(self) -> list[str]:
        """Properties the job expects nothing of whose search ran out of budget: no verdict."""
        return [p for p, v in self.verdicts.items() if p not in self.job.expect and v.status == "incomplete"]


def roar_events(result: JobResult, verdict: Verdict) -> Optional[list]:
    """The ROAR-level events of a counterexample (jobs on a spec), per step: a list of event lists."""
    roar = getattr(result, "roar", None)
    if roar is None or verdict.counterexample is None:
        return None
    from ..roar.explore import path_events
    model, start, explorer = roar
    cx = verdict.counterexample
    edges = list(cx.prefix) + list(cx.cycle)
    events = path_events(model, start, path_steps(explorer, edges))
    per_step: list = [[] for _ in edges]
    for ev in events:
        per_step[ev.step - 1].append(ev)
    return per_step


def counterexample_steps(graph: StateGraph, verdict: Verdict, result: Optional[JobResult] = None) -> list[dict]:
    """The counterexample as trace records, with the ROAR-level events of jobs on a spec."""
    cx = verdict.counterexample
    events = roar_events(result, verdict) if result is not None else None
    out = []
    edges = list(cx.prefix) + list(cx.cycle)
    # the steps as one run takes them (a lasso's cycle in the names its stem gave: search.path_steps)
    described = graph.describe_steps(edges) if graph.describe_steps else None
    for loop, part in ((False, cx.prefix), (True, cx.cycle)):
        for e in part:
            if described is not None:
                rec = described[len(out)]
            else:
                rec = graph.describe_edge(e) if graph.describe_edge else {"rule": graph.labels.names[graph.label[e]]}
            rec = dict(rec)
            rec["group"] = graph.groups.names[int(graph.group[e])]
            evs = events[len(out)] if events is not None else []
            rec["event"] = (evs[0].as_json() if len(evs) == 1 else
                            {"kind": "several", "events": [x.as_json() for x in evs]}) if evs else None
            rec["loop"] = loop
            out.append(rec)
    return out


def safe_name(res, prop: str) -> str:
    """The file stem of a job's picture or trace: the job name (or the stem a check run gave it,
    ``res.file_stem``: two jobs of one name) with unsafe characters replaced."""
    name = getattr(res, "file_stem", None) or res.job.name
    return "".join(ch if ch.isalnum() or ch in "-_" else "_" for ch in name) + f".{prop}"


def save_counterexample(result: JobResult, prop: str, folder: Path) -> Path:
    v = result.verdicts[prop]
    steps = counterexample_steps(result.graph, v, result)
    path = folder / f"{safe_name(result, prop)}.jsonl"
    job = result.job
    # paths are recorded for people to read; replay never opens them (docs/trust.md): it takes
    # the model from its command line and compares the fingerprint of its sources
    where = ({"spec": str(job.spec), "request": job.request,
              "functional": str(job.functional) if job.functional else None} if job.is_roar
             else {"model": str(job.model), "start": job.start})
    if getattr(job, "crashes", None):   # the model was compiled with these crashes ([faults])
        where["crash"], where["max_crashes"] = list(job.crashes.agents), job.crashes.bound
    if getattr(job, "time", None):      # ... and in the timed mode (replay recompiles the same model)
        where.update(job.time.header())
    if job.is_roar and getattr(result, "roar", None) is not None:   # the pairs of make; make the job checked (TCA reads them)
        header_pairs = {"seq_pairs": [[p.a, p.b, p.where, p.a_text, p.b_text, p.kept]
                                      for p in result.roar[2].system.pairs]}
    else:
        header_pairs = {}
    robot = getattr(result, "robot", None)
    if robot is not None:   # robot-backed: what replay --on-robot needs to drive the same robot
        header_pairs["robot"] = robot.header(job.robot.scenario)
        node = robot.explorer.states[v.counterexample.final_state].node
        if prop == "robot-invariant" and node.bad:   # where the robot broke it (mid-advance, maybe)
            _i, why, t, pose = node.bad[0]
            header_pairs["robot"]["violation"] = {"t": round(t, 4), "pose": [round(x, 6) for x in pose],
                                                  "why": why}
    if robot is None:   # what replay re-decides on the model (verify/claims.py)
        claim = trace_claim(job, prop)
        if claim:
            header_pairs["claim"] = claim
    header = {"kind": "counterexample", "property": prop, **where, **header_pairs, "fingerprint": result.fingerprint,
              "job": str(result.job.path), "shape": v.counterexample.kind,
              "final_state": result.graph.describe_state(v.counterexample.final_state)
              if result.graph.describe_state else []}
    write_trace(path, header, steps)
    return path
