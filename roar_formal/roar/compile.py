"""The compiler from a checked agent spec to CLF: declarations and an initial context.

The generic behaviour (request state machine, logic and executive layers,
error and concurrency handling) is ``framework.clf``. This module adds what is
particular to a spec:

* one constant per agent, variable (a cell holding the value), task, recipe,
  function and constraint (a target agent and a predicate);
* the tables the framework's backward clauses read: pre- and post-conditions
  of tasks, recipes of a task with their preference and constraint domain,
  candidates of each predicate (found by the logic layer's ``prove`` at
  compile time, see :func:`_candidates`), alternatives for the calling-context
  search;
* one forward rule per statement site of a recipe (``set``, ``let``,
  ``make``, ``ensure``, ``wait``, ``assert``, ``abort``, a functional-layer
  call, a read that runs a task), per pre-condition check, and per
  constraint (reading the agent's variables when the constraint is received
  and when its tasks are done);
* the outcomes of each functional-layer primitive as rules (for exploration),
  unless the run is driven by Python callables;
* the initial context: every cell with its initial value, an empty mask per
  agent, and the request.

Expressions are compiled to ``pexp`` terms evaluated by the framework's
``peval`` in one step: a statement reads the cells it needs as premises (the
values substituted as ``pl V``), function calls and reads of task-initialised
variables become earlier sites that push their result on the recipe's locals.
"""

from __future__ import annotations

import math
import re
from dataclasses import dataclass, field
from fractions import Fraction
from typing import Optional, Union

from ..clf import surface as S
from ..clf.build import (BUILT, Comment, Rule, args_of, backward, decl, exec_, fact, format_items, format_term,
                         head_of, number, q, query, string, tensor)
from ..clf.terms import format_number
from ..errors import Pos, RoarError, UnsupportedError, did_you_mean, written_at
from . import ast as a
from .checks import CheckedSpec, typed_request
from .spec import checked_spec
from ..clf.program import Program
from .framework import extend_framework, extend_signature, framework_text, parsed_part, with_framework
from .functional import DEFAULT_OUTCOMES, Outcome, Registry
from .incompatible import incompatible_tasks
from .pretty import format_expr, format_stmt

__all__ = ["compile_spec", "CompiledModel", "Site", "Crashes", "CRASH_RULES", "Timing", "TIME_MODES", "timing_of"]

_OPS = {"==": "o_eq", "!=": "o_ne", "<": "o_lt", "<=": "o_le", ">": "o_gt", ">=": "o_ge",
        "+": "o_add", "-": "o_sub", "*": "o_mul", "&&": "o_and", "||": "o_or"}
#: a recipe's pre-condition check reads its request's handler (the error context a hole: EC or EC1)
HS_CHECK = "hs R (h_rchk T P Cs Sc Rc) {} F Pl W"
#: a timed re-check of a held ensure is due (at tick Dk, its timer taken off the list)
TIMER_DUE = ("clock Dk", "tmrs Lk", "!tm_rm Dk Lk Lk1")
#: ... and a logic activation its request's handler
HS_LOGIC = "hs R (h_lq I) {} F Pl W"
#: depth budget of the logic layer's proof search (8.2: limit)
PROOF_BUDGET = 4
#: the logic layer's families whose goals the compile-time entailment tables (clf/backward.py,
#: _tabled_answers): the same candidates, found without re-proving each subgoal per proof
TABLED = frozenset({"hyp"})


def nat(k: int) -> S.Expr:
    """``k`` as a unary natural (``s (s z)``)."""
    out = q("z")
    for _ in range(k):
        out = q("s {}", out)
    return out


def num_lit(x) -> str:
    """A number as a CLF literal (exact; the engine's own printing of number literals)."""
    text = format_number(Fraction(repr(x)) if isinstance(x, float) else Fraction(x))
    if "/" in text:
        raise RoarError(f"the number {text} has no exact decimal form")
    return text


def num_tree(x) -> S.Expr:
    """A number as a literal of the model: exact, and only one with a decimal form (the printed
    model must read back as itself)."""
    num_lit(x)
    return number(Fraction(repr(x)) if isinstance(x, float) else Fraction(x))


def vlist(items: list) -> S.Expr:
    """A list value ``vcons X1 (... vnil)``."""
    out = q("vnil")
    for x in reversed(items):
        out = q("vcons {} {}", x, out)
    return out


def code_list(sites: list, tail="cnil") -> S.Expr:
    """A recipe's code ``ccons S1 (... cnil)`` (or ending in ``tail``)."""
    out = q("{}", tail)
    for x in reversed(sites):
        out = q("ccons {} {}", x, out)
    return out


def key_text(e: S.Expr) -> str:
    """A term's text as the model prints it in argument position (parenthesised when applied):
    the order of predicate keys (the ``cands_i`` tables are numbered in it)."""
    text = format_term(e)
    return f"({text})" if isinstance(e, (S.App, S.Bang)) else text


#: the crash rules (CRASH_RULES_TEXT) the scheduler of a run never chooses: the runner takes them
#: at the steps ``--crash`` names (docs/semantics.md, "Crashes")
CRASH_RULES = frozenset({"crash", "back", "back_armed"})


#: the forward rules of crashes, added only to a spec compiled with them (the declarations and
#: backward clauses they use are in framework.clf, section "faults"): a model without faults has
#: not one more rule, so its committed-choice runs draw the same schedule as before
CRASH_RULES_TEXT = """
% the agent goes down (its own fairness group; only an armed agent: see the crash plan), while
% it handles a request: down and idle, it would differ from up in nothing a step could show
% before a request reached it, and a crash then is the crash with that request just sent
crash : carmed A -o cleft (s N) -o cep A T -o !ep_next T T1 -o rq R A C J K -o hs R Ph EC F Pl W
         -o {cleft N * cep A T1 * rq R A C J K * hs R Ph EC F Pl W}.
% it comes back once nothing is committed in its mask any more (the dead requests released their
% tasks), with its variables as they were; `back_armed` may crash again while crashes are left
back : cep A T -o !ep_next T T1 -o !ep_up T1 -o mask A vnil -o {cep A T1 * mask A vnil}.
back_armed : cep A T -o !ep_next T T1 -o !ep_up T1 -o mask A vnil -o cleft (s N)
              -o {cep A T1 * mask A vnil * cleft (s N) * carmed A}.

% a dead request fails, its tasks released; an activation serving it first stops (below)
unavailable : hs R Ph EC F Pl _ -o !unav_idle Ph -o rq R A C J K -o cep A E -o !ep_dead F E -o rs R _
               -o mask A M -o !mrm M Pl M1
               -o {rq R A C J K * cep A E * rs R s_failure * ecf R (vcons (vunavail A) EC) * mask A M1}.
unavailable_write : hs R (h_write _) EC F Pl _ -o wrq R _ -o rq R A C J K -o cep A E -o !ep_dead F E -o rs R _
               -o mask A M -o !mrm M Pl M1
               -o {rq R A C J K * cep A E * rs R s_failure * ecf R (vcons (vunavail A) EC) * mask A M1}.
unavailable_run : hs R (h_run _ _ _) EC F Pl _ -o rdone R _ k_crash -o rq R A C J K -o cep A E -o !ep_dead F E
               -o rs R _ -o mask A M -o !mrm M Pl M1
               -o {rq R A C J K * cep A E * rs R s_failure * ecf R (vcons (vunavail A) EC) * mask A M1}.
unavailable_check : hs R (h_rchk _ _ _ _ _) EC F Pl _ -o chk I R _ _ -o ctl I m_run _ _ -o rstat I _
               -o rq R A C J K -o cep A E -o !ep_dead F E -o rs R _ -o mask A M -o !mrm M Pl M1
               -o {rq R A C J K * cep A E * rs R s_failure * ecf R (vcons (vunavail A) EC) * mask A M1}.
unavailable_check_call : hs R (h_rchk _ _ _ _ _) EC F Pl _ -o chk I R _ _ -o ctl I (m_call D _) _ _ -o rstat I _
               -o rq R A C J K -o cep A E -o !ep_dead F E -o rs R _ -o mask A M -o !mrm M Pl M1
               -o {rq R A C J K * cep A E * rs R s_failure * ecf R (vcons (vunavail A) EC) * mask A M1 * orphan D}.

% an activation serving a dead request stops: a crashed agent runs nothing, not even the end block;
% the requests it holds are aborted as at a recipe's end (cleanup_abort), then it ends with k_crash
% (recipe_end_failed), which fails its request (unavailable_run) or completes its abort (aborted)
crash_stop_run : act I R T Rc N -o hs R Ph EC F Pl W -o rq R A C J K -o cep A E -o !ep_dead F E
                  -o alive I -o ctl I m_run _ L -o rstat I _
                  -o {act I R T Rc N * hs R Ph EC F Pl W * rq R A C J K * cep A E
                      * ending I k_crash * ctl I m_run (ccons s_done cnil) L * rstat I go}.
crash_stop_call : act I R T Rc N -o hs R Ph EC F Pl W -o rq R A C J K -o cep A E -o !ep_dead F E
                  -o alive I -o ctl I (m_call D _) _ L -o rstat I _
                  -o {act I R T Rc N * hs R Ph EC F Pl W * rq R A C J K * cep A E
                      * ending I k_crash * ctl I m_run (ccons s_done cnil) L * rstat I go * orphan D}.
crash_stop_make : act I R T Rc N -o hs R Ph EC F Pl W -o rq R A C J K -o cep A E -o !ep_dead F E
                  -o alive I -o ctl I (m_make _) _ L -o rstat I _
                  -o {act I R T Rc N * hs R Ph EC F Pl W * rq R A C J K * cep A E
                      * ending I k_crash * ctl I m_run (ccons s_done cnil) L * rstat I go}.
crash_stop_block : act I R T Rc N -o hs R Ph EC F Pl W -o rq R A C J K -o cep A E -o !ep_dead F E
                  -o alive I -o ctl I (m_block _) _ L -o rstat I _
                  -o {act I R T Rc N * hs R Ph EC F Pl W * rq R A C J K * cep A E
                      * ending I k_crash * ctl I m_run (ccons s_done cnil) L * rstat I go}.
crash_stop_end : act I R T Rc N -o hs R Ph EC F Pl W -o rq R A C J K -o cep A E -o !ep_dead F E
                  -o ending I Kn -o !not_crash Kn -o ctl I m_run _ L -o rstat I _
                  -o {act I R T Rc N * hs R Ph EC F Pl W * rq R A C J K * cep A E
                      * ending I k_crash * ctl I m_run (ccons s_done cnil) L * rstat I go}.
crash_stop_end_call : act I R T Rc N -o hs R Ph EC F Pl W -o rq R A C J K -o cep A E -o !ep_dead F E
                  -o ending I Kn -o !not_crash Kn -o ctl I (m_call D _) _ L -o rstat I _
                  -o {act I R T Rc N * hs R Ph EC F Pl W * rq R A C J K * cep A E
                      * ending I k_crash * ctl I m_run (ccons s_done cnil) L * rstat I go * orphan D}.
crash_stop_end_make : act I R T Rc N -o hs R Ph EC F Pl W -o rq R A C J K -o cep A E -o !ep_dead F E
                  -o ending I Kn -o !not_crash Kn -o ctl I (m_make _) _ L -o rstat I _
                  -o {act I R T Rc N * hs R Ph EC F Pl W * rq R A C J K * cep A E
                      * ending I k_crash * ctl I m_run (ccons s_done cnil) L * rstat I go}.
crash_stop_end_block : act I R T Rc N -o hs R Ph EC F Pl W -o rq R A C J K -o cep A E -o !ep_dead F E
                  -o ending I Kn -o !not_crash Kn -o ctl I (m_block _) _ L -o rstat I _
                  -o {act I R T Rc N * hs R Ph EC F Pl W * rq R A C J K * cep A E
                      * ending I k_crash * ctl I m_run (ccons s_done cnil) L * rstat I go}.
"""


#: the rules that join crashes and the logic activation (task pre-conditions that call the
#: functional layer), added only to a spec compiled with both: a dead request whose decision is
#: still making its calls fails as in the other phases (``unavailable``), the activation gone
CRASH_LOGIC_TEXT = """
unavailable_lq : hs R (h_lq I) EC F Pl _ -o lsnap I _ -o ctl I m_run _ _ -o rstat I _ -o rq R A C J K -o cep A E
               -o !ep_dead F E -o rs R _ -o mask A M -o !mrm M Pl M1
               -o {rq R A C J K * cep A E * rs R s_failure * ecf R (vcons (vunavail A) EC) * mask A M1}.
unavailable_lq_call : hs R (h_lq I) EC F Pl _ -o lsnap I _ -o ctl I (m_call D _) _ _ -o rstat I _ -o rq R A C J K
               -o cep A E -o !ep_dead F E -o rs R _ -o mask A M -o !mrm M Pl M1
               -o {rq R A C J K * cep A E * rs R s_failure * ecf R (vcons (vunavail A) EC) * mask A M1 * orphan D}.
"""

#: the fairness group of the steps of time (the tick, wakes, re-checks that find nothing to do)
TIME_GROUP = "the clock"

#: the longest cycle of the clock (in ticks, plus one): each tick can be a state of its own
MAX_CYCLE = 1001

#: the time modes of a job or a run (docs/semantics.md, "Time")
TIME_MODES = ("untimed", "timed")

#: the declarations and rules of the discrete clock, added only to a spec compiled in timed mode
#: (docs/semantics.md, "Time"): an untimed model is, to the byte, the model without them
TIME_TEXT = """
% time (opt-in, docs/semantics.md "Time"): a discrete clock. One tick is the greatest common
% divisor of the spec's periods; the clock counts ticks modulo a cycle longer than the longest
% period, so a deadline (a tick number) is never ambiguous. `tmrs L` lists, sorted, the ticks at
% which something is due (a sleeping wait or assert, a held ensure to re-check); the clock
% advances only while something is due and nothing is due now (the due steps are urgent), and it
% goes back to 0 when nothing waits on time any more (only differences of ticks matter).
clock : number -> type.
tmrs : val -> type.
tnext : number -> number -> type.            % compiled: the next tick of the cycle
tafter : number -> number -> number -> type. % compiled: tafter K T D: K ticks after tick T is tick D
eperiod : cst -> number -> type.             % compiled: the period (ticks) of an ensured constraint
m_sleep : number -> mode.                    % a wait or an assert sleeps until tick D
h_heldt : number -> phase.                   % a held ensure, re-checked at tick D
tm_ins : number -> val -> val -> type.
tmi_at : bool -> number -> number -> val -> val -> type.
tmi_nil : tm_ins D vnil (vcons (vnum D) vnil).
tmi_cons : tm_ins D (vcons (vnum X) L) R <- nlt X D B <- tmi_at B D X L R.
tmia_f : tmi_at ff D X L (vcons (vnum D) (vcons (vnum X) L)).
tmia_t : tmi_at tt D X L (vcons (vnum X) R) <- tm_ins D L R.
tm_rm : number -> val -> val -> type.
tmr_at : bool -> number -> number -> val -> val -> type.
tmr_cons : tm_rm D (vcons (vnum X) L) R <- neqb X D B <- tmr_at B D X L R.
tmra_t : tmr_at tt _ _ L L.
tmra_f : tmr_at ff D X L (vcons (vnum X) R) <- tm_rm D L R.
tm_free : number -> val -> type.             % nothing is due at tick T
tmf_nil : tm_free _ vnil.
tmf_cons : tm_free T (vcons (vnum X) L) <- num_ne X T <- tm_free T L.
clk_norm : val -> number -> number -> type.  % the clock once the timers are L: 0 when none is left
cn_nil : clk_norm vnil _ 0.
cn_cons : clk_norm (vcons _ _) T T.

% the clock advances (its own fairness group: time passes in every fair run)
tick : clock T -o tmrs (vcons X L) -o !tm_free T (vcons X L) -o !tnext T T1 -o {clock T1 * tmrs (vcons X L)}.
% a sleeping wait or assert is due: it evaluates its condition again (its statement's rules)
wake : ctl I (m_sleep D) C E -o clock D -o tmrs L -o !tm_rm D L L1 -o !clk_norm L1 D T1
        -o {ctl I m_run C E * clock T1 * tmrs L1}.
kill_sleep : kill I K -o alive I -o rstat I _ -o ctl I (m_sleep D) _ _ -o act I R T Rc N -o !endcode Rc C
        -o clock T0 -o tmrs L -o !tm_rm D L L1 -o !clk_norm L1 T0 T1
        -o {rstat I go * ending I K * ctl I m_run C vnil * act I R T Rc N * clock T1 * tmrs L1}.
% a held ensure of a periodic constraint is re-checked at its period (compiled: ensure_check_cN,
% ensure_broken_cN); it is armed when it becomes held
held_arm : hs R h_held EC F Pl W -o rq R A C J k_ensure -o !eperiod C P -o clock T -o !tafter P T D
        -o tmrs L -o !tm_ins D L L1
        -o {hs R (h_heldt D) EC F Pl W * rq R A C J k_ensure * clock T * tmrs L1}.
aborted_held : abortreq R -o hs R (h_heldt D) _ _ Pl _ -o rs R _ -o rq R A _ _ _ -o ppz R _ -o mask A M -o !mrm M Pl M1
        -o clock T -o tmrs L -o !tm_rm D L L1 -o !clk_norm L1 T T1
        -o {mask A M1 * clock T1 * tmrs L1}.
"""


#: the rules that join crashes and time, added only to a spec compiled timed with crashes: what a
#: crash stops or fails also gives up its deadline, so a dead agent keeps no timer alive
CRASH_TIME_TEXT = """
% a sleeping activation (a wait or an assert of its body or its end block) of a dead request stops
% at once, its deadline gone, as crash_stop_* stop the others
crash_stop_sleep : act I R T Rc N -o hs R Ph EC F Pl W -o rq R A C J K -o cep A E -o !ep_dead F E
                  -o alive I -o ctl I (m_sleep D) _ L -o rstat I _ -o clock T0 -o tmrs Lt -o !tm_rm D Lt Lt1
                  -o !clk_norm Lt1 T0 T1
                  -o {act I R T Rc N * hs R Ph EC F Pl W * rq R A C J K * cep A E
                      * ending I k_crash * ctl I m_run (ccons s_done cnil) L * rstat I go * clock T1 * tmrs Lt1}.
crash_stop_end_sleep : act I R T Rc N -o hs R Ph EC F Pl W -o rq R A C J K -o cep A E -o !ep_dead F E
                  -o ending I Kn -o !not_crash Kn -o ctl I (m_sleep D) _ L -o rstat I _ -o clock T0 -o tmrs Lt
                  -o !tm_rm D Lt Lt1 -o !clk_norm Lt1 T0 T1
                  -o {act I R T Rc N * hs R Ph EC F Pl W * rq R A C J K * cep A E
                      * ending I k_crash * ctl I m_run (ccons s_done cnil) L * rstat I go * clock T1 * tmrs Lt1}.
% a held ensure waiting for its periodic re-check, of a dead request, fails as the other phases do
% (unavailable), and its re-check is cancelled
unavailable_heldt : hs R (h_heldt D) EC F Pl _ -o rq R A C J K -o cep A E -o !ep_dead F E -o rs R _
               -o mask A M -o !mrm M Pl M1 -o clock T0 -o tmrs Lt -o !tm_rm D Lt Lt1 -o !clk_norm Lt1 T0 T1
               -o {rq R A C J K * cep A E * rs R s_failure * ecf R (vcons (vunavail A) EC) * mask A M1
                   * clock T1 * tmrs Lt1}.
"""

@dataclass(frozen=True)
class Timing:
    """The time abstraction a spec is compiled with (docs/semantics.md, "Time"): ``mode``
    "untimed" (no clock: the model of the sections before it, to the byte) or "timed" (a discrete
    clock; the periods of wait, assert and ensure are modelled). ``wait_timeout`` (ms, timed
    only): a wait with a period whose condition was still false at its last poll at or after that
    long fails with a timeout. ``where`` holds the positions in the job file of the mode and the
    timeout (for errors), or None."""

    mode: str = "untimed"
    wait_timeout: Optional[int] = None
    where: tuple = ()

    def __bool__(self) -> bool:
        return self.mode == "timed"

    def header(self) -> dict:
        """What a trace header records (replay recompiles the same model from it)."""
        return {"time": self.mode, **({"wait_timeout": self.wait_timeout} if self.wait_timeout is not None else {})}


def nothing_timed(model) -> Optional[str]:
    """Why asking for the timed mode changes nothing on this compiled model (its spec writes no
    period), or None. The library compiles such a model (it is the untimed one); the job, the
    command line and the API refuse it, so that no one believes a timed check was made."""
    if getattr(model, "timing", None) and model.tick_ms is None:
        return ("the timed mode models the periods of wait, assert and ensure, and this spec writes none "
                "(e.g. wait(c, 100)): nothing would be timed and the model is the untimed one; drop the time "
                "option, or give the statements periods")
    return None


def timeout_unused(model) -> Optional[str]:
    """Why the ``wait_timeout`` of a timed compiled model changes nothing (its spec has no ``wait``
    with a period: the timeout applies to those alone), or None. As with :func:`nothing_timed`, the
    library compiles such a model; the job (at its ``wait_timeout``), the command line and the API
    refuse it, so that no one believes a timeout was checked."""
    timing = getattr(model, "timing", None)
    if not timing or timing.wait_timeout is None:
        return None
    if any(isinstance(n, a.Wait) and n.period is not None for n in a.walk(model.spec)):
        return None
    return (f"wait_timeout applies to the waits with a period (e.g. wait(c, 100)), and this spec has none "
            f"(a wait without a period, an assert and an ensure never time out): the timeout of "
            f"{timing.wait_timeout} ms would change nothing; drop it, or give the waits periods")


def timing_of(value) -> Optional[Timing]:
    """A Timing from None, a mode name or a Timing; None when untimed."""
    if value is None:
        return None
    if isinstance(value, str):
        if value not in TIME_MODES:
            raise RoarError(f"time must be one of {', '.join(TIME_MODES)}, not {value!r}")
        value = Timing(value)
    if not isinstance(value, Timing):
        raise RoarError(f"time must be one of {', '.join(TIME_MODES)} or a Timing, not {value!r}")
    if value.mode not in TIME_MODES:
        raise RoarError(f"time must be one of {', '.join(TIME_MODES)}, not {value.mode!r}",
                        value.where[0] if value.where else None)
    t = value.wait_timeout
    if t is not None and (isinstance(t, bool) or not isinstance(t, int) or t < 1):
        raise RoarError(f"wait_timeout is a whole number of milliseconds, at least 1, not {t!r}",
                        value.where[1] if len(value.where) > 1 else None)
    if t is not None and value.mode != "timed":
        raise RoarError("wait_timeout needs the timed mode (time = \"timed\" in a job, --time timed on the "
                        "command line): an untimed wait never times out",
                        value.where[1] if len(value.where) > 1 else None)
    return value if value else None


@dataclass(frozen=True)
class Crashes:
    """Agents that may crash and come back (docs/semantics.md, "Crashes"): opt-in, per job
    (``[faults] crash``) or per run (``--crash``). With no agents the model is the one compiled
    without faults, to the byte.

    ``bound`` is the number of crashes in a run, all agents together. In exploration
    (``scheduled`` false) a crash plan decided at the start says which agents may crash; in a run
    (``scheduled`` true) every listed agent is armed from the start, and the runner fires each
    crash (and comeback) at the step it was given. ``where`` holds, per agent, the position of its
    name in the job file (for errors), or None."""

    agents: tuple = ()
    bound: int = 1
    scheduled: bool = False
    where: tuple = ()

    def __bool__(self) -> bool:
        return bool(self.agents)


@dataclass
class Site:
    """A compiled statement site: what the trace printer says about its rule."""

    const: str
    kind: str          # set let make ensure wait assert abort call run-task pre expr
    agent: str
    task: str
    recipe: str
    pos: Pos
    text: str
    var: Optional[str] = None       # set: the variable written
    function: Optional[str] = None  # call: the function
    cst: Optional[str] = None       # make/ensure: the constraint constant
    period_ms: Optional[float] = None  # wait/assert: the period written (ms), for runs in simulated time


@dataclass
class CompiledModel:
    """A spec compiled to CLF, with the tables that map CLF names back to the spec."""

    spec: a.Spec
    text: str                        # framework + generated declarations (what `roar-verify compile` prints)
    init: str                        # the initial context (a positive type)
    cells: dict[str, tuple[str, str]] = field(default_factory=dict)      # cell -> (agent, var)
    cell_types: dict[str, str] = field(default_factory=dict)             # cell -> type
    agents: dict[str, str] = field(default_factory=dict)                 # const -> agent
    tasks: dict[str, tuple[str, str]] = field(default_factory=dict)      # const -> (agent, task)
    recipes: dict[str, tuple[str, str, str]] = field(default_factory=dict)
    csts: dict[str, tuple[str, str]] = field(default_factory=dict)       # const -> (agent, predicate text)
    functions: dict[str, tuple[Optional[str], str]] = field(default_factory=dict)  # const -> (owner, name)
    fn_types: dict[str, str] = field(default_factory=dict)               # const -> result type
    fn_params: dict[str, list] = field(default_factory=dict)             # const -> parameter types
    sites: dict[str, Site] = field(default_factory=dict)
    rule_sites: dict[str, str] = field(default_factory=dict)   # rule of a statement site -> the site const
    request_cst: str = ""
    request_agent: str = ""
    structs: dict[str, list[str]] = field(default_factory=dict)          # type -> field names
    opaques: set[str] = field(default_factory=set)                       # opaque types (agent::name)
    field_types: dict[str, dict[str, str]] = field(default_factory=dict)
    functional: str = "abstract"
    where_cells: dict[str, list[str]] = field(default_factory=dict)      # cst -> cells its where clause writes
    spec_text: str = ""              # the generated declarations alone, printed (for people)
    items: tuple = ()                # the generated declarations as syntax trees (what extends the framework)
    call_sites: dict[str, list] = field(default_factory=dict)   # function const -> positions of its calls
    candidates: dict[str, list] = field(default_factory=dict)   # cst -> (agent, task) the logic layer proved
    incompatible: dict[tuple[str, str], list[str]] = field(default_factory=dict)  # (agent, task) -> tasks it masks (4.3)
    hypotheses: dict[str, list] = field(default_factory=dict)    # cst -> (agent, task, hypothesis) candidates under a hypothesis
    unused_rules: list[str] = field(default_factory=list)
    fair_outcomes: dict[str, str] = field(default_factory=dict)   # outcome rule -> its fairness group (fair=True)   # agent::rule the logic layer cannot use (they call functions)
    # (with crashes, also the crash and comeback rules -> their own groups: neither is a step of an agent)
    crashes: Optional[Crashes] = None   # the agents that may crash (None: no faults)
    epochs: dict[str, int] = field(default_factory=dict)          # epoch sentinel task -> crashes so far
    timing: Optional[Timing] = None     # timed mode (None: untimed; docs/semantics.md, Time)
    # the functional layer compiled against: its primitives' outcomes (replay reads an answer as the
    # outcome that covers it)
    registry: Optional[Registry] = field(default=None, repr=False, compare=False)
    tick_ms: Optional[int] = None       # timed, with a clock: one tick in ms (the gcd of the periods)
    cycle: Optional[int] = None         # ... the clock counts ticks modulo this

    def site_of_rule(self, rule: str) -> Optional[Site]:
        """The statement site a compiled rule (``stN_kind``, ``stN_kind_false``, ...) belongs to, or None."""
        c = self.rule_sites.get(rule)
        return self.sites.get(c) if c is not None else None

    def program(self):
        """The CLF program (cached)."""
        if getattr(self, "_program", None) is None:
            self._program = with_framework([x for x in self.items if not isinstance(x, Comment)], "<compiled model>")
        return self._program


#: why a function call is refused where the logic layer reads an expression symbolically
#: (docs/semantics.md, "Where the logic layer calls no function")
_NO_CALL = {
    "post": "a task post-condition: the logic layer proves at compile time, symbolically, which tasks' "
            "post-conditions entail a constraint, and a function's value exists only once it is called "
            "(a task's pre-conditions and a recipe's conditions may call functions)",
    "constraint": "a constraint: a constraint is a predicate on variables, which the target agent matches "
                  "with its tasks' post-conditions and checks again and again (at the end, while an ensure "
                  "holds) on its own; a call has a value only where a recipe makes it: call it in the recipe "
                  "and send the value in a where clause",
    "request": "a request: a request from outside has no functional layer to call; write the value",
    "last-error": "the constraint of last_error?(C): C names a constraint a recipe sends, and a constraint "
                  "calls no function, so no failure could ever be of C",
    None: "an expression the logic layer reads symbolically (the logic layer evaluates calls only in task "
          "pre-conditions)",
}


def pushed_env(n: int) -> S.Expr:
    """The locals ``E`` with ``n`` values pushed on top (``vcons Hn (... (vcons H1 E))``)."""
    pat = q("E")
    for i in range(n):
        pat = q("vcons {} {}", f"H{i + 1}", pat)
    return pat


class _Ctx:
    """Compilation state of one statement: cells read, sites hoisted before it, locals.

    Calls and reads of task-initialised variables are hoisted first
    (:meth:`_Compiler.prepare`): each becomes a site run before the statement;
    a call pushes its result on the locals. The statement's own rule then
    sees every hoisted value, and pops them.
    """

    def __init__(self, comp: "_Compiler", agent: a.Agent, env: list[str],
                 snapshot: bool = False, run_tasks: bool = True, task: str = "", recipe: str = ""):
        self.comp = comp
        self.agent = agent
        self.env = env                 # names of locals, innermost first ("" for call results)
        self.snapshot = snapshot       # cells as `pc C` (evaluated against a snapshot)
        self.run_tasks = run_tasks     # reads of task-initialised variables run the task first
        self.task, self.recipe = task, recipe
        self.reads: dict[str, str] = {}    # cell -> metavariable
        self.hoisted: list[str] = []       # sites to run before the statement, in order
        self.slots: dict[int, int] = {}    # id(Call) -> position of its result from the bottom
        self.ran: set[str] = set()         # cells whose task was run
        self.pushed = 0
        self.logic: dict[str, str] = {}    # logic variables of a domain rule -> CLF variables (pexps)
        self.purpose: Optional[str] = None  # what a snapshot expression is (for the reason of a refusal)

    def var(self, cell: str) -> S.Expr:
        if self.snapshot:
            return q("pc {}", cell)
        return q("pl {}", self.meta(cell))

    def meta(self, cell: str) -> str:
        """The metavariable the statement's rule reads ``cell`` into."""
        v = self.reads.get(cell)
        if v is None:
            v = f"V{len(self.reads) + 1}"
            self.reads[cell] = v
        return v

    def sub(self) -> "_Ctx":
        """A context for a hoisted site: same locals, its own reads."""
        c = _Ctx(self.comp, self.agent, self.env, self.snapshot, self.run_tasks, self.task, self.recipe)
        c.slots = self.slots
        return c

    def envpat(self) -> S.Expr:
        """The locals with the values hoisted for this statement on top (popped by its rule)."""
        return pushed_env(self.pushed)


class _Compiler:
    def __init__(self, checked: CheckedSpec, registry: Optional[Registry], functional: str,
                 crashes: Optional[Crashes] = None, timing: Optional[Timing] = None):
        spec = checked.spec
        self.timing = timing if timing else None
        self.clock = False                        # timed mode and the spec writes a period
        self.tick_ms, self.cycle = 1, 1
        self.periods: set[int] = set()            # periods (ticks) something sleeps for
        self.eperiods: dict[str, int] = {}        # ensured constraint -> its period (ticks), the shortest
        self.timeouts: dict[str, str] = {}        # wait site -> its timeout site
        self.time_steps: set[str] = set()          # compiled rules that are steps of time (TIME_GROUP)
        self.division_sites: Optional[list] = None
        self.timed_assert_code: Optional[list] = None   # a timed assert's code: it sleeps before its calls
        self.crashes = crashes if crashes else None
        self.crash_agents: set[str] = set(crashes.agents) if crashes else set()
        self.checker_sites: set[str] = set()      # calls hoisted in a recipe's pre-condition check
        self.logic_sites: set[str] = set()        # sites of the logic activation (task pre-conditions that call)
        self.start_sites: set[str] = set()        # sites of the initialisers run at start
        # a constraint sent with another where clause than its first: a variant constant of its
        # own (the same identity number: the same constraint for the error context)
        self.variant_of: dict[str, str] = {}
        self.variants: dict[tuple[str, tuple[str, ...]], str] = {}
        self.sent_variants: dict[tuple[str, str, str], set[str]] = {}   # (agent, task, recipe) -> variants
        self.sent_runs: dict[tuple[str, str, str], set[str]] = {}   # (agent, task, recipe) -> task-run csts
        self.asks: list[tuple[a.Agent, str, str, list[a.Recipe]]] = []   # (agent, recipe, cst it emits, others)
        # agent -> its task pre-conditions that call the functional layer: (pseudo-cell, condition, task);
        # the logic layer evaluates them before each decision (docs/semantics.md, "The logic layer")
        self.logic_pres: dict[str, list[tuple[str, a.Expr, a.Task]]] = {}
        self.guards: dict[str, tuple[str, str]] = {}   # compiled rule -> (agent, how its request is found)
        self.spec = spec
        self.checked = checked   # the types the static checks found (the compiler re-checks nothing)
        self.registry = registry
        self.functional = functional
        self.out: list = []   # the model's items (syntax trees; comments for the printed model)
        self.model = CompiledModel(spec, "", "", functional=functional)
        self.n_sites = 0
        self.cst_by_key: dict[tuple[str, str], str] = {}
        self.cst_pexp: dict[str, str] = {}   # cst -> pexp (snapshot form)
        self.cst_ast: dict[str, tuple[a.Agent, a.Expr]] = {}
        self.task_run_csts: dict[str, str] = {}   # task const -> cst const
        self.predicates: dict[str, str] = {}      # pexp text -> agent (for cands)
        self.ensured: set[str] = set()            # constraints sent by an ensure somewhere
        self.failure_budgets: dict[str, int] = {}  # function const -> failures left (max_failures)
        self.predicate_exprs: dict[str, tuple[a.Agent, a.Expr]] = {}   # pexp text -> (agent, qualified predicate)
        # cst -> the equalities its where clause establishes with literal values (hypotheses of the
        # logic layer, 4.3); None once two sends of it disagree (then it has none)
        self.where_hyps: dict[str, Optional[tuple[str, ...]]] = {}
        self.hyp_keys: dict[str, tuple[str, tuple[str, ...]]] = {}   # pwhere key -> (predicate, hypotheses)
        self.rules: list[Rule] = []
        self.pending_fns: dict[str, tuple[Optional[str], str, str]] = {}

    # ------------------------------------------------------------ names
    def cell(self, agent: str, var: str) -> str:
        c = f"v_{agent}_{var}"
        self.model.cells[c] = (agent, var)
        return c

    def task_c(self, agent: str, task: str) -> str:
        return f"t_{agent}_{task}"

    def recipe_c(self, agent: str, task: str, recipe: str) -> str:
        return f"r_{agent}_{task}_{recipe}"

    def fn_c(self, owner: Optional[str], name: str) -> str:
        c = f"f_{owner}_{name}" if owner else f"f_{name}"
        self.model.functions[c] = (owner, name)
        return c

    def site(self, kind: str, ag: a.Agent, task: str, recipe: str, pos: Pos, text: str, **kw) -> str:
        self.n_sites += 1
        c = f"pp{self.n_sites}_{kind.replace('-', '_')}"   # the rule of the site is st<n>_<kind>
        self.model.sites[c] = Site(c, kind, ag.name, task, recipe, pos, text, **kw)
        self.out.append(decl(c, "site"))
        return c

    def sites_by_number(self) -> dict[str, str]:
        """``ppN`` -> the site const ``ppN_kind``: the rules of site N are named ``ppN_...`` while
        compiling (``stN_...`` in the model)."""
        return {c.split("_", 1)[0]: c for c in self.model.sites}

    # ------------------------------------------------------------ values
    def default(self, ty: Optional[str]) -> S.Expr:
        if ty in ("int", "double"):
            return q("vnum 0")
        if ty == "bool":
            return q("vbool ff")
        if ty in ("string", "identifier") or ty is None:
            return q("vstr {}", string(""))
        fields = self.model.structs.get(ty)
        if fields is not None:
            return q("vrec {}", vlist([self.default(self.field_types[ty][f]) for f in fields]))
        return q("vopq 0")

    def value(self, v, ty: Optional[str]) -> S.Expr:
        """A Python value as a CLF value term (for initial values and outcomes)."""
        if isinstance(v, _Opaque):
            return q("vopq {}", v.handle)
        if isinstance(v, bool):
            return q("vbool tt") if v else q("vbool ff")
        if isinstance(v, (int, float, Fraction)):
            return q("vnum {}", num_tree(v))
        if isinstance(v, str):
            return q("vstr {}", string(v))
        if isinstance(v, (tuple, list)):
            return q("vrec {}", vlist([self.value(x, None) for x in v]))
        if isinstance(v, dict) and ty in self.model.structs:
            return q("vrec {}", vlist([self.value(v[f], self.field_types[ty][f]) for f in self.model.structs[ty]]))
        raise RoarError(f"cannot represent the value {v!r} in the model")

    # ------------------------------------------------------------ expressions
    def ty(self, e: a.Expr, cx: _Ctx) -> Optional[str]:
        return self.checked.type_of(e)

    def prepare(self, e: a.Expr, cx: _Ctx) -> None:
        """Hoist the calls and task runs of ``e``, in evaluation order (arguments first)."""
        if isinstance(e, a.Call):
            for x in e.args:
                self.prepare(x, cx)
            self.hoist_call(e, cx)
            return
        if isinstance(e, (a.Name, a.Remote)) and not cx.snapshot and cx.run_tasks:
            if isinstance(e, a.Name) and e.name in cx.env:
                return
            owner = cx.agent if isinstance(e, a.Name) else self.spec.agent(e.agent)
            task = owner.reading_task(e.name)
            cell = self.cell(owner.name, e.name)
            if task is not None and cell not in cx.ran:
                cx.ran.add(cell)
                self.hoist_task_run(owner, e.name, task, cx, e.pos)
            return
        if isinstance(e, a.LastError):
            return
        for ch in e.children():
            if isinstance(ch, a.Expr):
                self.prepare(ch, cx)

    def hoist_task_run(self, owner: a.Agent, var: str, task: str, cx: _Ctx, pos: Pos) -> None:
        """Reading ``var`` runs its task first (4.2: an initialiser naming a task), as a task-run request,
        unless the registry abstracts it (:meth:`hoist_abstract_read`)."""
        if self.abstract_read(owner, var) is not None:
            self.hoist_abstract_read(owner, var, cx, pos)
            return
        tc = self.task_c(owner.name, task)
        run_c = self.task_run_cst(owner, task)
        s = self.site("run-task", cx.agent, cx.task, cx.recipe, pos, f"read {owner.name}::{var} (runs {task})")
        stamp_p, stamp_o, failed = self.stamp(owner.name)
        self.rules.append(Rule(
            s, [q("ctl I m_run (ccons {} C) E", s), q("rstat I go"), q("act I R0 T0 Rc0 N"), *stamp_p],
            [q("ctl I (m_make r) C E"), q("rstat I go"), q("act I R0 T0 Rc0 (s N)"), q("owns I r ff"),
             q("rq r {} {} I (k_task {})", f"a_{owner.name}", run_c, tc), q("rs r s_pending"), q("ppz r ff"),
             q("hs r (h_tasks (vcons (vtsk {}) vnil)) vnil {} vnil vnone", tc, failed), *stamp_o], fresh=("r",)))
        cx.hoisted.append(s)
        self.sent_runs.setdefault((cx.agent.name, cx.task, cx.recipe), set()).add(run_c)

    def abstract_read(self, owner: a.Agent, var: str):
        """The registry entry ``agent::var`` that abstracts the task of a task-initialised variable
        for exploration (docs/spec-language.md, the functional layer), or None: only in the
        abstract functional layer (a run with Python callables runs the task)."""
        if self.functional != "abstract" or self.registry is None:
            return None
        prim = self.registry.lookup(var, owner.name)
        return prim if prim is not None and prim.name == f"{owner.name}::{var}" else None

    def hoist_abstract_read(self, owner: a.Agent, var: str, cx: _Ctx, pos: Pos) -> None:
        """A read of a task-initialised variable that the registry abstracts: instead of running
        the task, one step of the functional layer whose outcomes (the entry's) write the
        variable (``writes``), or fail the read as a failed primitive fails its statement."""
        fc = f"fv_{owner.name}_{var}"
        vty = self.checked.var_types.get((owner.name, var))
        self.model.functions[fc] = (owner.name, var)
        self.model.fn_types[fc] = vty
        self.model.fn_params[fc] = []
        self.pending_fns[fc] = (owner.name, var, vty)
        s = self.site("call", cx.agent, cx.task, cx.recipe, pos, f"read {owner.name}::{var} (abstracted)",
                      function=f"{owner.name}::{var}")
        self.model.call_sites.setdefault(fc, []).append(pos)
        self.rules.append(Rule(s, [q("ctl I m_run (ccons {} C) E", s), q("rstat I go")],
                               [q("pending {} vnil d", fc), q("ctl I (m_call d {}) C E", s), q("rstat I go")],
                               fresh=("d",)))
        cx.hoisted.append(s)
        cx.env.insert(0, "")   # (its result is pushed and popped with the statement's; the read is the cell's)
        cx.pushed += 1

    def hoist_call(self, e: a.Call, cx: _Ctx) -> None:
        found = self.spec.resolve_function(cx.agent, e)
        if found:
            owner, _decl = found[0]
            result_ty = self.checked.fn_sigs.get((owner, e.name), (None, None))[0]
        elif e.name in a.BUILTINS:
            owner, result_ty = None, a.BUILTINS[e.name][0]
        else:
            raise UnsupportedError(f"call of '{e.qualified}'", e.pos)
        if cx.snapshot:
            raise UnsupportedError(f"a function call ('{e.qualified}') in " + _NO_CALL.get(cx.purpose, _NO_CALL[None]),
                                   e.pos)
        sub = cx.sub()
        args = [self.pexp(x, sub) for x in e.args]
        fc = self.fn_c(owner, e.name)
        self.model.fn_types[fc] = result_ty
        self.model.fn_params[fc] = list(self.checked.fn_sigs.get((owner, e.name), (None, []))[1] or [])
        self.pending_fns[fc] = (owner, e.name, result_ty)
        s = self.site("call", cx.agent, cx.task, cx.recipe, e.pos, format_expr(e), function=e.qualified)
        if not cx.run_tasks:   # a call of a recipe's pre-condition: a checker activation makes it
            self.checker_sites.add(s)
        self.model.call_sites.setdefault(fc, []).append(e.pos)
        prem, outs = self.premises(sub)
        vals = [f"A{i + 1}" for i in range(len(args))]
        evals = [q("!peval vnil E vnil {} {}", p, v) for p, v in zip(args, vals)]
        self.rules.append(Rule(
            s, [q("ctl I m_run (ccons {} C) E", s), q("rstat I go"), *prem, *evals],
            [q("pending {} {} d", fc, vlist(vals)), q("ctl I (m_call d {}) C E", s), q("rstat I go"), *outs],
            fresh=("d",)))
        self.call_division_failures(e, s, sub, cx)
        cx.hoisted.append(s)
        cx.slots[id(e)] = len(cx.env)
        cx.env.insert(0, "")
        cx.pushed += 1

    def call_division_failures(self, e: a.Call, s: str, sub: _Ctx, cx: _Ctx) -> None:
        """A division by zero in the arguments of the call of site ``s`` (made by :meth:`hoist_call`):
        the call is not made (its site cannot evaluate them), and, per divisor, a rule gives the
        located reason ``division by zero: D is 0 in WHERE`` as the same division outside a call
        does: in a statement, a local failure of the recipe (WHERE is the statement, set by
        :meth:`division_failures`); in a recipe's pre-condition check, the recipe is not acceptable,
        the division in the request's error context; in an initialiser run at start, the request
        from outside fails before it is sent. (Divisions in the arguments of a nested call are its
        own call site's.)"""
        divisors = [d for x in e.args for d in self.own_divisors(x)]
        if not divisors:
            return
        zeros = [self.pexp(d, sub) for d in divisors]   # (before the call's result is pushed)
        prem, outs = self.premises(sub)
        starting = getattr(self, "starting", None)   # (an initialiser run at start: its text)
        pending = self.__dict__.setdefault("call_divs", {})   # call site -> [(division site, divisor)]
        for k, (d, dp) in enumerate(zip(divisors, zeros)):
            rule = f"{s}_div{chr(97 + k)}"
            zero = q("!peval vnil E vnil {} (vnum 0)", dp)
            head = [q("ctl I m_run (ccons {} C) E", s), q("rstat I go")]
            if starting is not None:
                where = self.division_site(cx.agent, cx.task, cx.recipe, d, starting)
                self.rules.append(Rule(rule, [*head, *prem, zero, q("sgate R"), q("hs R _ _ _ _ _")],
                                       [q("rs R s_failure"), q("ecf R (vcons (vsite {}) vnil)", where), *outs]))
            elif not cx.run_tasks:   # a recipe's pre-condition check (a checker activation)
                where = self.division_site(cx.agent, cx.task, cx.recipe, d, self.pre_condition_of(e, cx))
                # (it reads the checker and the handler itself, as the pre-condition's site does:
                # named stN_call_divX already, with crashes it is guarded as that site's rules are)
                rule = "st" + rule[2:]
                self.guards[rule] = (cx.agent.name, "chk")
                self.rules.append(Rule(
                    rule, [*head, q("chk I R Rc N"), q(HS_CHECK, "EC"), *prem, zero, q("!num_add N 1000 N1"),
                           q("!ec_add (k_local {}) EC EC1", where)],
                    [q("ctl I m_run (ccons s_pdone cnil) E"), q("rstat I go"), q("chk I R Rc N1"),
                     q(HS_CHECK, "EC1"), *outs]))
            else:   # a statement: its text is known once its site is made (division_failures)
                where = self.division_site(cx.agent, cx.task, cx.recipe, d, format_expr(e))
                pending.setdefault(s, []).append((where, d))
                self.rules.append(Rule(
                    rule, [*head, *prem, zero, q("act I R0 T0 Rc0 N")],
                    [q("ctl I m_run cnil E"), q("rstat I go"), q("act I R0 T0 Rc0 N"),
                     q("kill I (k_local {})", where), *outs]))

    @staticmethod
    def pre_condition_of(e: a.Call, cx: _Ctx) -> str:
        """The recipe pre-condition that makes call ``e`` (its text, for a division's reason)."""
        for t in cx.agent.tasks:
            for r in t.recipes:
                if (t.name, r.name) == (cx.task, cx.recipe):
                    for p in r.pre:
                        if any(n is e for n in a.walk(p)):
                            return f"pre-condition {format_expr(p)}"
        return f"pre-condition call {format_expr(e)}"

    def pexp(self, e: a.Expr, cx: _Ctx) -> S.Expr:
        """``e`` as a pexp term (after :meth:`prepare`): cells read as premises, calls as their pushed results."""
        if isinstance(e, a.BoolLit):
            return q("pl (vbool tt)") if e.value else q("pl (vbool ff)")
        if isinstance(e, a.IntLit):
            return q("pl (vnum {})", e.value)
        if isinstance(e, a.DoubleLit):
            return q("pl (vnum {})", num_tree(Fraction(repr(e.value))))
        if isinstance(e, a.StringLit):
            return q("pl (vstr {})", string(e.value))
        if isinstance(e, a.Name):
            if e.name in cx.logic:
                return q("{}", cx.logic[e.name])
            if e.name in cx.env:
                return q("ploc {}", nat(cx.env.index(e.name)))
            return cx.var(self.cell(cx.agent.name, e.name))
        if isinstance(e, a.Remote):
            return cx.var(self.cell(e.agent, e.name))
        if isinstance(e, a.Call):
            if id(e) not in cx.slots:
                self.hoist_call(e, cx)   # (a call in a pre-condition, compiled without prepare)
            return q("ploc {}", nat(len(cx.env) - 1 - cx.slots[id(e)]))
        if isinstance(e, a.Field):
            ty = self.ty(e.base, cx)
            fields = self.model.structs.get(ty, [])
            if e.name not in fields:
                raise UnsupportedError(f"field '{e.name}' of a value of type {ty}", e.pos)
            return q("pfield {} {}", nat(fields.index(e.name)), self.pexp(e.base, cx))
        if isinstance(e, a.Unary):
            inner = self.pexp(e.operand, cx)
            return q("pnot {}", inner) if e.op == "!" else q("pneg {}", inner)
        if isinstance(e, a.Binary):
            op = _OPS.get(e.op)
            if e.op == "/":
                op = "o_idiv" if self.ty(e.left, cx) == "int" else "o_div"
            if op is None:
                raise UnsupportedError(f"operator '{e.op}'", e.pos)
            return q("pbin {} {} {}", op, self.pexp(e.left, cx), self.pexp(e.right, cx))
        if isinstance(e, a.LastError):
            c = self.cst_for(cx.agent, e.constraint, None, purpose="last-error")
            return q("plast {}", c)
        raise UnsupportedError(f"expression {format_expr(e)}", e.pos)

    def premises(self, cx: _Ctx, writes: Optional[dict[str, str]] = None) -> tuple[list, list]:
        """Premises reading the cells of ``cx`` (and the cells written), and the facts that put them back."""
        writes = writes or {}
        prem, outs = [], []
        for cell, v in cx.reads.items():
            prem.append(q("contains {} {}", cell, v))
            outs.append(q("contains {} {}", cell, writes.get(cell, v)))
        for cell, v in writes.items():
            if cell not in cx.reads:
                prem.append(q("contains {} _", cell))
                outs.append(q("contains {} {}", cell, v))
        return prem, outs

    # ------------------------------------------------------------ constraints
    def cst_for(self, sender: a.Agent, pred: a.Expr, target: Optional[str], purpose: str = "constraint") -> str:
        """The constant of a constraint: the same (target, predicate) gives the same constant."""
        tmp = a.Constraint(pred, (), pos=pred.pos)
        target = target or tmp.target(sender.name) or sender.name
        tag = self.spec.agent(target)
        pcx = _Ctx(self, tag, [], snapshot=True)
        pcx.purpose = purpose
        # the sender's unqualified names are its own variables
        text = self.pexp(self._qualify(pred, sender.name), pcx)
        key = (target, text)
        c = self.cst_by_key.get(key)
        if c is None:
            c = f"c{len(self.cst_by_key) + 1}_{target}"
            self.cst_by_key[key] = c
            self.cst_pexp[c] = text
            self.cst_ast[c] = (tag, self._qualify(pred, sender.name))
            self.model.csts[c] = (target, format_expr(pred))
            self.predicates[text] = target
            self.predicate_exprs.setdefault(text, self.cst_ast[c])
        return c

    def _qualify(self, e: a.Expr, own: str) -> a.Expr:
        """Unqualified names of agent ``own`` written ``own::name`` (a predicate read by another agent)."""
        import dataclasses
        if isinstance(e, a.Name):
            out: a.Expr = a.Remote(own, e.name, pos=e.pos)
        elif isinstance(e, a.Call):
            return e
        else:
            kw = {}
            for f in dataclasses.fields(e):
                if not f.compare:
                    continue
                v = getattr(e, f.name)
                if isinstance(v, a.Expr):
                    kw[f.name] = self._qualify(v, own)
            out = dataclasses.replace(e, **kw) if kw else e
        self.checked.same_type(out, e)   # the rewritten expression has the checked one's type
        return out

    def task_run_cst(self, owner: a.Agent, task: str) -> str:
        tc = self.task_c(owner.name, task)
        c = self.task_run_csts.get(tc)
        if c is None:
            c = f"crun_{owner.name}_{task}"
            self.task_run_csts[tc] = c
            self.model.csts[c] = (owner.name, f"run task {task}")
        return c

    # ------------------------------------------------------------ recipes
    def block(self, ag: a.Agent, task: a.Task, r: a.Recipe, stmts) -> list[str]:
        env: list[str] = []
        code: list[str] = []
        for st in stmts:
            code += self.stmt(ag, task, r, st, env)
        return code

    def stmt(self, ag: a.Agent, task: a.Task, r: a.Recipe, st: a.Stmt, env: list[str],
             kind_name: Optional[str] = None) -> list[str]:
        cx = _Ctx(self, ag, env, task=task.name, recipe=r.name)
        text = format_stmt(st)
        kind = {a.Set: "set", a.Let: "let", a.ExprStmt: "expr", a.Make: "make", a.Ensure: "ensure",
                a.Abort: "abort", a.Wait: "wait", a.Assert: "assert"}[type(st)]
        # hoist calls and task runs
        if isinstance(st, (a.Set, a.Let)):
            self.prepare(st.value, cx)
        elif isinstance(st, a.ExprStmt):
            self.prepare(st.expr, cx)
        elif isinstance(st, (a.Wait, a.Assert)):
            self.prepare(st.cond, cx)
        elif isinstance(st, (a.Make, a.Ensure)):
            for v in st.constraint.writes(ag.name).values():
                self.prepare(v, cx)
        site_kw = {}
        if isinstance(st, a.Set):
            site_kw["var"] = st.target.name
        if isinstance(st, (a.Wait, a.Assert)) and isinstance(st.period, (a.IntLit, a.DoubleLit)):
            site_kw["period_ms"] = float(st.period.value)
        if isinstance(st, (a.Make, a.Ensure)):
            c = st.constraint
            for n in a.walk(c.expr):
                if isinstance(n, a.Name) and n.name in env:
                    raise UnsupportedError(
                        f"a local ('{n.name}') in a constraint: a constraint is a predicate on variables, "
                        f"which the target agent decides and checks again on its own, after the recipe's "
                        f"locals are gone; send the value in a where clause", n.pos)
            target = c.target(ag.name) or ag.name
            site_kw["cst"] = self.where_cst(self.cst_for(ag, c.expr, c.target(ag.name)),
                                            [self.cell(target, w) for w in c.writes(ag.name)])
        s = self.site(kind_name or kind, ag, task.name, r.name, st.pos, text, **site_kw)
        division_sites = None
        E = cx.envpat()
        head = [q("ctl I m_run (ccons {} C) {}", s, E), q("rstat I go")]
        if isinstance(st, a.Set):
            cell = self.cell(ag.name, st.target.name)
            val = self.pexp(st.value, cx)
            prem, outs = self.premises(cx, {cell: "X"})
            self.rules.append(Rule(s, [*head, *prem, q("!peval vnil {} vnil {} X", E, val)],
                                   [q("ctl I m_run C E"), q("rstat I go"), *outs]))
        elif isinstance(st, a.Let):
            val = self.pexp(st.value, cx)
            prem, outs = self.premises(cx)
            self.rules.append(Rule(s, [*head, *prem, q("!peval vnil {} vnil {} X", E, val)],
                                   [q("ctl I m_run C (vcons X E)"), q("rstat I go"), *outs]))
        elif isinstance(st, a.ExprStmt):
            self.rules.append(Rule(s, head, [q("ctl I m_run C E"), q("rstat I go")]))
        elif isinstance(st, (a.Make, a.Ensure)):
            self.send(ag, st, cx, s, head)
        elif isinstance(st, a.Abort):
            k = env.index(st.handle)
            # abort gives up ownership: the request's emitter becomes `irel`, so that nothing of it
            # (a temporary failure, a continue) reaches this activation afterwards
            self.rules.append(Rule(
                s, [*head, q("act I R0 T0 Rc0 (s N)"), q("!nth E {} (vreq R)", nat(k)), q("owns I R _"),
                    q("rq R Ar Cr I Kr")],
                [q("ctl I m_run C E"), q("rstat I go"), q("act I R0 T0 Rc0 N"), q("abortreq R"),
                 q("rq R Ar Cr irel Kr")]))
        elif self.ticks_of(st) is not None:   # timed mode: a wait or an assert with a period
            self.timed_wait(st, s, cx, kind)
            division_sites = self.division_sites
        else:  # wait, assert
            cond = self.pexp(st.cond, cx)
            prem, outs = self.premises(cx)
            self.rules.append(Rule(s, [*head, *prem, q("!peval vnil {} vnil {} (vbool tt)", E, cond)],
                                   [q("ctl I m_run C E"), q("rstat I go"), *outs]))
            false = [*head, *prem, q("!peval vnil {} vnil {} (vbool ff)", E, cond)]
            if kind == "assert":
                # the recipe fails (a local failure); nothing more of the body runs
                self.rules.append(Rule(f"{s}_false", [*false, q("act I R0 T0 Rc0 N")],
                                       [q("ctl I m_run cnil E"), q("rstat I go"), q("act I R0 T0 Rc0 N"),
                                        q("kill I (k_local {})", s), *outs]))
            elif cx.hoisted:
                # calls or task runs in the predicate: poll, i.e. run them again
                again = code_list([*cx.hoisted, s], "C")
                self.rules.append(Rule(f"{s}_false", false, [q("ctl I m_run {} E", again), q("rstat I go"), *outs]))
            else:
                # block until one of the variables read changes
                snap = vlist(list(cx.reads.values()))
                self.rules.append(Rule(f"{s}_false", false,
                                       [q("ctl I (m_block {}) (ccons {} C) E", snap, s), q("rstat I go"), *outs]))
                fresh = {c: f"W{i + 1}" for i, c in enumerate(cx.reads)}
                self.rules.append(Rule(
                    f"{s}_wake", [q("ctl I (m_block Old) (ccons {} C) E", s),
                                  *(q("contains {} {}", c, w) for c, w in fresh.items()),
                                  q("!val_eq Old {} ff", vlist(list(fresh.values())))],
                    [q("ctl I m_run (ccons {} C) E", s), *(q("contains {} {}", c, w) for c, w in fresh.items())]))
        self.division_failures(st, s, cx, kind, division_sites)
        for _ in range(cx.pushed):
            env.pop(0)
        if isinstance(st, a.Let):
            env.insert(0, st.name)
        if isinstance(st, a.Ensure) and st.handle:
            env.insert(0, st.handle)
        code, self.timed_assert_code = self.timed_assert_code or cx.hoisted + [s], None
        return code

    def note_where_hyps(self, cst: str, cells: list[str], values: list[a.Expr]) -> None:
        """Record the equalities ``cell == literal`` a send of ``cst`` establishes by its where
        clause; sends that disagree (or a value that is not a literal) leave the constraint with
        no hypothesis, as if it had no where clause (fewer candidates, never wrong ones)."""
        hyps = []
        for cell, v in zip(cells, values):
            lit = self.literal(v)
            if lit is None:
                self.where_hyps[cst] = None
                return
            hyps.append(q("fatom (pbin o_eq (pc {}) (pl {}))", cell, lit))
        got = tuple(hyps)
        if cst in self.where_hyps and self.where_hyps[cst] != got:
            self.where_hyps[cst] = None
        else:
            self.where_hyps[cst] = got

    def literal(self, e: a.Expr) -> Optional[S.Expr]:
        """The value of a literal expression (a where value), or None."""
        if isinstance(e, (a.IntLit, a.DoubleLit, a.BoolLit, a.StringLit)) or (
                isinstance(e, a.Unary) and e.op == "-" and isinstance(e.operand, (a.IntLit, a.DoubleLit))):
            return self.const_value(e)
        return None

    def key_hypotheses(self) -> None:
        """A constraint with where hypotheses is decided on its own key, ``pwhere P Hs`` (evaluated
        as ``P``), whose candidates the logic layer proves under ``Hs`` (4.3: "a solution under
        certain hypotheses")."""
        for c, hyps in sorted(self.where_hyps.items()):
            if not hyps:
                continue
            p = self.cst_pexp[c]
            key = q("pwhere {} {}", p, vlist([q("vform {}", h) for h in hyps]))
            self.cst_pexp[c] = key
            self.predicates[key] = self.predicates[p]
            self.hyp_keys[key] = (p, hyps)

    # ------------------------------------------------------------ time (opt-in)
    def setup_clock(self) -> None:
        """Timed mode: the tick (the gcd of the periods written, in ms) and the cycle of the clock
        (longer than the longest period, in ticks). A period must be a literal number of
        milliseconds, at least 1 (located errors). A spec without a period has no clock."""
        if not self.timing:
            return
        found = []
        for ag in self.spec.agents:
            for t in ag.tasks:
                for r in t.recipes:
                    for st in list(r.body) + list(r.end):
                        if isinstance(st, (a.Wait, a.Assert, a.Ensure)) and st.period is not None:
                            e = st.period
                            if not isinstance(e, a.IntLit):
                                raise UnsupportedError(
                                    f"in the timed mode a period must be a literal number of milliseconds, "
                                    f"not '{format_expr(e)}'", e.pos)
                            if e.value < 1:
                                raise RoarError(f"a period is at least 1 ms, not {e.value}", e.pos)
                            found.append((e.value, e.pos))
        if not found:
            return
        self.tick_ms = math.gcd(*(v for v, _pos in found))
        longest, where = max(found, key=lambda vp: vp[0])
        self.cycle = longest // self.tick_ms + 1
        if self.cycle > MAX_CYCLE:
            raise RoarError(f"the timed mode's clock would count {self.cycle - 1:,} ticks of {self.tick_ms} ms for "
                            f"this period of {longest} ms (the tick is the greatest common divisor of the spec's "
                            f"periods); at most {MAX_CYCLE - 1:,}: write periods with a larger common divisor",
                            where)
        self.clock = True
        self.model.tick_ms, self.model.cycle = self.tick_ms, self.cycle
        # (declared before the recipes' code, which a timed assert's polled site is part of)
        self.out.append(decl("spoll", q("site -> number -> site")))   # site S polled again, K polls left before its timeout

    def ticks_of(self, st) -> Optional[int]:
        """The period of a statement in ticks (timed mode, with a clock), or None."""
        if not self.clock or getattr(st, "period", None) is None:
            return None
        return st.period.value // self.tick_ms

    def sleep(self, ticks: int, again, outs: list) -> tuple[list, list]:
        """Premises and conclusions of going to sleep for ``ticks`` (the code ``again`` runs at the wake)."""
        self.periods.add(ticks)
        return ([q("clock Tk"), q("!tafter {} Tk Dk", ticks), q("tmrs Lk"), q("!tm_ins Dk Lk Lk1")],
                [q("ctl I (m_sleep Dk) {} E", again), q("rstat I go"), *outs, q("clock Tk"), q("tmrs Lk1")])

    def timed_wait(self, st, s: str, cx: _Ctx, kind: str) -> None:
        """A wait or an assert with a period, in timed mode (docs/semantics.md, "Time").

        wait: evaluated when reached; when false, it sleeps for its period and is evaluated again
        at the wake (its calls and task runs made again first). With a timeout of T ms, the poll
        at or after T (the K-th, K = ceil(T / period)) that finds it false fails the recipe
        locally, at a site of kind ``timeout`` (the error context's entry says so): the polls left
        are counted in the code (``spoll S K``). assert: it sleeps for its period when reached and
        is evaluated at the wake (``spoll S 0``), failing the recipe if false."""
        E = cx.envpat()
        ticks = self.ticks_of(st)
        cond = self.pexp(st.cond, cx)
        prem, outs = self.premises(cx)
        holds = q("!peval vnil {} vnil {} (vbool tt)", E, cond)
        fails = q("!peval vnil {} vnil {} (vbool ff)", E, cond)
        go = [q("ctl I m_run C E"), q("rstat I go"), *outs]
        stop = [q("ctl I m_run cnil E"), q("rstat I go"), q("act I R0 T0 Rc0 N")]

        def at(code) -> list:
            return [q("ctl I m_run (ccons {} C) {}", code, E), q("rstat I go"), *prem]

        def code(last) -> S.Expr:
            return code_list([*cx.hoisted, last], "C")
        if kind == "assert":
            # it sleeps first, then makes its calls and is evaluated, once (its code is
            # s, the hoisted calls, the polled site: see stmt)
            polled = q("spoll {} 0", s)
            sp, so = self.sleep(ticks, "C", [])
            self.rules.append(Rule(f"{s}_sleep", [q("ctl I m_run (ccons {} C) E", s), q("rstat I go"), *sp], so))
            self.timed_assert_code = [s] + cx.hoisted + [polled]
            self.rules.append(Rule(s, [*at(polled), holds], go))
            self.rules.append(Rule(f"{s}_false", [*at(polled), fails, q("act I R0 T0 Rc0 N")],
                                   [*stop, q("kill I (k_local {})", s), *outs]))
            self.division_sites = [polled]
            return
        timeout = self.timing.wait_timeout
        polls = -(-timeout // st.period.value) if timeout is not None else 0   # 0: no timeout
        self.rules.append(Rule(s, [*at(s), holds], go))
        sp, so = self.sleep(ticks, code(q("spoll {} {}", s, polls)), outs)
        self.rules.append(Rule(f"{s}_false", [*at(s), fails, *sp], so))
        polled = q("spoll {} Kp", s) if polls else q("spoll {} 0", s)
        self.division_sites = [s, polled]
        self.rules.append(Rule(f"{s}_poll", [*at(polled), holds], go))
        # a poll that finds the condition false is a step of time, not of the agent (its own
        # fairness group: an agent polling for ever does not hide its other steps from fairness)
        self.time_steps.add(f"{s}_poll_false")
        if not polls:
            sp, so = self.sleep(ticks, code(polled), outs)
            self.rules.append(Rule(f"{s}_poll_false", [*at(polled), fails, *sp], so))
            return
        sp, so = self.sleep(ticks, code(q("spoll {} Kp1", s)), outs)
        self.rules.append(Rule(f"{s}_poll_false", [*at(polled), fails, q("!num_lt 1 Kp"), q("!num_sub Kp 1 Kp1"), *sp],
                               so))
        site = self.model.sites[s]
        where = self.site("timeout", cx.agent, cx.task, cx.recipe, st.pos,
                          f"timeout: {site.text} did not hold within {timeout} ms "
                          f"({polls} poll{'s' if polls > 1 else ''} every {st.period.value} ms)")
        self.timeouts[s] = where
        self.rules.append(Rule(f"{s}_timeout", [*at(q("spoll {} 1", s)), fails, q("act I R0 T0 Rc0 N")],
                               [*stop, q("kill I (k_local {})", where), *outs]))

    def time_declarations(self) -> list[str]:
        """Timed mode: the clock's declarations and rules, its tables, the ensures' periods."""
        n = self.cycle
        out = [Comment(""), *parsed_part(TIME_TEXT, "<framework: time>")]
        if self.crashes:
            out += parsed_part(CRASH_TIME_TEXT, "<framework: crashes and time>")
        out += [fact(f"tnext_{k}", "tnext {} {}", k, (k + 1) % n) for k in range(n)]
        out += [fact(f"tafter_{p}_{k}", "tafter {} {} {}", p, k, (k + p) % n) for p in sorted(self.periods) for k in range(n)]
        out += [fact(f"eperiod_{c}", "eperiod {} {}", c, p) for c, p in sorted(self.eperiods.items())]
        # time is no agent's step: the tick, the wakes and the re-checks that find nothing have their
        # own fairness group (a spelling no agent can have)
        for r in ("tick", "wake", *(f"ensure_check_{c}" for c in self.eperiods),
                  *(("st" + x[2:]) if x.startswith("pp") else x for x in self.time_steps)):
            self.model.fair_outcomes[r] = TIME_GROUP
        return out

    def division_failures(self, st: a.Stmt, s: str, cx: _Ctx, kind: str, at: Optional[list] = None) -> None:
        """A division by zero in the statement's expressions is a local failure of the recipe at
        this site (the engine's division has no value there, so without these rules the recipe
        would block, and the explorer would call it a deadlock). In an initialiser run at start
        (``self.starting``, :meth:`start_code`) it is an error of the start instead: the request
        from outside, not sent yet, fails with the division as its error context."""
        # the divisions in the arguments of the statement's calls: their call sites' rules
        # (call_division_failures), whose reason names the statement
        for x in cx.hoisted:
            for where, d in self.__dict__.get("call_divs", {}).pop(x, []):
                self.model.sites[where].text = (f"division by zero: {format_expr(d)} is 0 in "
                                                f"{self.model.sites[s].text}")
        if isinstance(st, (a.Set, a.Let)):
            roots = [st.value]
        elif isinstance(st, (a.Wait, a.Assert)):
            roots = [st.cond]
        elif isinstance(st, (a.Make, a.Ensure)):
            roots = list(st.constraint.writes(cx.agent.name).values())
        else:
            return
        # (those in a call's arguments are its call site's: the statement sees the call's result)
        divisors = [d for e in roots for d in self.own_divisors(e)]
        if not divisors:
            return
        E = cx.envpat()
        prem, outs = self.premises(cx)
        starting = getattr(self, "starting", None)   # (an initialiser run at start: its text)
        for k, d in enumerate(divisors):
            where = self.division_site(cx.agent, cx.task, cx.recipe, d, starting or self.model.sites[s].text)
            for j, head in enumerate(at or [s]):   # (timed: the statement's polled forms too)
                zero = q("!peval vnil {} vnil {} (vnum 0)", E, self.pexp(d, cx))
                reached = [q("ctl I m_run (ccons {} C) {}", head, E), q("rstat I go"), *prem, zero]
                if starting is not None:
                    # at start (start_code): the agents cannot start; the request from outside,
                    # not sent yet, fails with the division as its error context
                    self.rules.append(Rule(f"{s}_div{chr(97 + k)}", [*reached, q("sgate R"), q("hs R _ _ _ _ _")],
                                           [q("rs R s_failure"), q("ecf R (vcons (vsite {}) vnil)", where), *outs]))
                    continue
                self.rules.append(Rule(
                    f"{s}_div{chr(97 + k)}{'_poll' * j}", [*reached, q("act I R0 T0 Rc0 N")],
                    [q("ctl I m_run cnil E"), q("rstat I go"), q("act I R0 T0 Rc0 N"), q("kill I (k_local {})", where),
                     *outs]))

    @staticmethod
    def own_divisors(e: a.Expr) -> list[a.Expr]:
        """The divisors of the divisions ``e`` evaluates itself, in evaluation order: not those in
        the arguments of its calls (their call sites evaluate them)."""
        out: list[a.Expr] = []
        if isinstance(e, a.Call):
            return out
        if isinstance(e, a.Binary) and e.op == "/":
            out.append(e.right)
        for ch in e.children():
            if isinstance(ch, a.Expr):
                out += _Compiler.own_divisors(ch)
        return out

    def division_site(self, ag: a.Agent, task: str, recipe: str, d: a.Expr, where: str) -> str:
        """The site naming a division by zero of divisor ``d`` in ``where`` (the reason a located
        failure gives: ``division by zero: D is 0 in WHERE``)."""
        return self.site("div", ag, task, recipe, d.pos, f"division by zero: {format_expr(d)} is 0 in {where}")

    def where_cst(self, base: str, cells: list[str]) -> str:
        """The constant a send of constraint ``base`` with a where clause writing ``cells`` uses:
        ``base`` itself for the first shape sent (and every send of it), a variant ``base_wK`` for
        another shape. A variant is decided, written and checked as its base is, with its own
        where cells; it has the base's identity number, so that the error context, ``last_error?``
        and the constraint domains see one constraint (hyper: the same predicate)."""
        known = self.where_cells.setdefault(base, cells)
        if known == cells:
            return base
        key = (base, tuple(cells))
        v = self.variants.get(key)
        if v is None:
            v = f"{base}_w{1 + sum(1 for b in self.variant_of.values() if b == base)}"
            self.variants[key] = v
            self.variant_of[v] = base
            self.cst_pexp[v] = self.cst_pexp[base]
            self.cst_ast[v] = self.cst_ast[base]
            self.model.csts[v] = self.model.csts[base]
            self.where_cells[v] = cells
        return v

    def send(self, ag: a.Agent, st, cx: _Ctx, s: str, head: str) -> None:
        """make / ensure (4.4, 8.3): a fresh request with the where values, owned by the activation."""
        c = st.constraint
        target = c.target(ag.name)
        writes = c.writes(ag.name)
        wvals = [self.pexp(v, cx) for v in writes.values()]
        cells = [self.cell(target, w) for w in writes]
        cst = self.where_cst(self.cst_for(ag, c.expr, target), cells)
        if cst in self.variant_of:
            self.sent_variants.setdefault((ag.name, cx.task, cx.recipe), set()).add(cst)
        self.note_where_hyps(cst, cells, list(writes.values()))
        prem, outs = self.premises(cx)
        names = [f"W{i + 1}" for i in range(len(wvals))]
        E = cx.envpat()
        evals = [q("!peval vnil {} vnil {} {}", E, p, w) for p, w in zip(wvals, names)]
        kind = "make" if isinstance(st, a.Make) else "ensure"
        if kind == "ensure":
            self.ensured.add(cst)
            ticks = self.ticks_of(st)
            if ticks is not None:   # timed: re-checked at its period (the shortest of its ensures)
                self.eperiods[cst] = min(ticks, self.eperiods.get(cst, ticks))
                self.periods.add(self.eperiods[cst])
        pairs = vlist([q("vpair (vcell {}) {}", c, w) for c, w in zip(cells, names)])
        stamp_p, stamp_o, failed = self.stamp(target)
        req = [q("rq r {} {} I {}", f"a_{target}", cst, f"k_{kind}"), q("rs r s_sent"), q("ppz r ff"), q("owns I r ff"),
               q("hs r h_select vnil {} vnil (vsome {})", failed, pairs)]
        if kind == "make":
            ctl = q("ctl I (m_make r) C E")
        else:
            ctl = q("ctl I m_run C (vcons (vreq r) E)") if st.handle else q("ctl I m_run C E")
        self.rules.append(Rule(
            s, [*head, q("act I R0 T0 Rc0 N"), *prem, *evals, *stamp_p],
            [*req, ctl, q("rstat I go"), q("act I R0 T0 Rc0 (s N)"), *outs, *stamp_o], fresh=("r",)))

    def recipe(self, ag: a.Agent, t: a.Task, r: a.Recipe) -> None:
        o = self.out
        rc = self.recipe_c(ag.name, t.name, r.name)
        body = self.block(ag, t, r, r.body)
        # the recipe's and the task's post-conditions are checked when the body is done:
        # a violated one fails the recipe with its reason (a local failure)
        for e, whose in [(e, "recipe") for e in r.post] + [(e, "task") for e in t.post]:
            for conj in a.conjuncts(e):
                sites = self.stmt(ag, t, r, a.Assert(conj, None, pos=conj.pos), [], kind_name="post")
                site = self.model.sites[sites[-1]]
                site.text = f"post-condition of {whose} {t.name if whose == 'task' else r.name}: {format_expr(conj)}"
                body += sites
        end = self.block(ag, t, r, r.end)
        end_code = end + ["s_done"]
        o.append(fact(f"body_{rc}", "bodycode {} {}", rc, code_list(body + ['s_end'] + end_code)))
        o.append(fact(f"end_{rc}", "endcode {} {}", rc, code_list(end_code)))
        # pre-condition checks, in a checker activation that counts the false ones
        env: list[str] = []
        pre_code = []
        for e in r.pre:
            cx = _Ctx(self, ag, env, run_tasks=False, task=t.name, recipe=r.name)
            self.prepare(e, cx)
            cond = self.pexp(e, cx)
            s = self.site("pre", ag, t.name, r.name, e.pos, format_expr(e))
            prem, outs = self.premises(cx)
            E = cx.envpat()
            checking = [q("ctl I m_run (ccons {} C) {}", s, E), q("rstat I go"), q("chk I R Rc N"), q(HS_CHECK, "EC"),
                        *prem]
            self.rules.append(Rule(
                s, [*checking, q("!peval vnil {} EC {} (vbool B)", E, cond), q("!pre_count B N N1")],
                [q("ctl I m_run C E"), q("rstat I go"), q("chk I R Rc N1"), q(HS_CHECK, "EC"), *outs]))
            # a division by zero: the pre-condition cannot be evaluated, so the recipe is not
            # acceptable (as when a call in it fails), the division in the request's error context
            for k, d in enumerate(self.own_divisors(e)):
                where = self.division_site(ag, t.name, r.name, d, f"pre-condition {format_expr(e)}")
                self.rules.append(Rule(
                    f"{s}_div{chr(97 + k)}",
                    [*checking, q("!peval vnil {} EC {} (vnum 0)", E, self.pexp(d, cx)), q("!num_add N 1000 N1"),
                     q("!ec_add (k_local {}) EC EC1", where)],
                    [q("ctl I m_run (ccons s_pdone cnil) E"), q("rstat I go"), q("chk I R Rc N1"), q(HS_CHECK, "EC1"),
                     *outs]))
            for _ in range(cx.pushed):
                env.pop(0)
            pre_code += cx.hoisted + [s]
        pre_code.append("s_pdone")
        o.append(fact(f"pre_{rc}", "precode {} {}", rc, code_list(pre_code)))
        dom = sorted({self.cst_for(ag, c.expr, c.target(ag.name)) for _, c in r.constraints()})
        o.append(fact(f"cdom_{rc}", "cdom {} {}", rc, vlist([q("vcst {}", c) for c in dom])))
        o.append(fact(f"rinfo_{rc}", "rinfo {} {} {} {}", rc, r.preference(), len(r.pre),
                      len(r.constraint_domain(ag.name))))
        # the calling-context search (5.3) at an activation of this recipe, for each constraint it
        # may emit: its rules are compiled once every constraint is known (calling_context_rules)
        for c in dom:
            others = [q for q in t.recipes if q is not r and
                      c not in {self.cst_for(ag, x.expr, x.target(ag.name)) for _, x in q.constraints()}]
            self.asks.append((ag, rc, c, others))
            for v in sorted(x for x in self.sent_variants.get((ag.name, t.name, r.name), ())
                            if self.variant_of[x] == c):   # (the same constraint, another where clause)
                self.asks.append((ag, rc, v, others))
        for run_c in sorted(self.sent_runs.get((ag.name, t.name, r.name), ())):
            self.asks.append((ag, rc, run_c, []))   # (a task run: no recipe avoids reading the variable)

    def calling_context_rules(self) -> None:
        """The calling-context search (5.3) at an activation ``Ik`` of a recipe ``rc`` that emitted
        the request ``Rk`` of ``c``, asked for the new request ``R`` (``cres R Rk``), serving
        request ``Rk1``: first another recipe of its task that avoids ``c`` and is acceptable in
        the current situation (:meth:`alternative_rules`), then another task set for ``Rk1``
        without its task, executable now (``ask_tasks_RC_C``), else ``Rk1``'s emitter is asked
        (``ask_caller_RC_C``).

        The task set is decided as a reselection would be (the framework's ``retask``: the
        predicate, a snapshot of every cell the agent's decisions read, its failed tasks and the
        task avoided, the mask without ``Rk1``'s own entries). An agent whose task pre-conditions
        call the functional layer decides through a logic activation, which cannot run inside
        this one step: there the task-set search is skipped (docs/semantics.md, Known gaps)."""
        snap_cells: dict[str, list[str]] = {}
        for c1 in self.cst_pexp:
            cells = snap_cells.setdefault(self.cst_ast[c1][0].name, [])
            cells += [x for x in self.snapshot_cells(c1) if x not in cells]
        for ag, rc, c, others in self.asks:
            cx = _Ctx(self, ag, [], run_tasks=False)
            cond = self.alternative_condition(others, cx) if others else None
            head = [q("cres R Rk"), q("rq Rk Ak {} Ik Kk", c), q("act Ik Rk1 Tk {} N", rc), q("alive Ik")]
            keep = [q("rq Rk Ak {} Ik Kk", c), q("act Ik Rk1 Tk {} N", rc), q("alive Ik")]
            no_alt = [q("!peval vnil vnil vnil {} (vbool ff)", cond)] if cond is not None else []
            if ag.name in self.logic_pres:
                prem, outs = self.premises(cx)
                if cond is not None:
                    self.alternative_rules(ag, rc, c, head + prem, keep + outs, cond)
                self.guards[f"ask_caller_{rc}_{c}"] = (ag.name, "ask")
                self.rules.append(Rule(f"ask_caller_{rc}_{c}", [*head, *prem, *no_alt], [*keep, *outs, q("cres R Rk1")]))
                continue
            snap = vlist([q("vpair (vcell {}) {}", cell, cx.meta(cell)) for cell in snap_cells.get(ag.name, [])])
            prem, outs = self.premises(cx)
            if cond is not None:
                self.alternative_rules(ag, rc, c, head + prem, keep + outs, cond)
            agent = f"a_{ag.name}"
            req = [q("hs Rk1 (h_run Tk P Ik) EC F Pl W"), q("rq Rk1 {} C1 J1 K1", agent), q("mask {} M", agent)]
            decide = [q("!mrm M Pl M0"), q("!mtasks M0 MT")]
            self.guards[f"ask_tasks_{rc}_{c}"] = self.guards[f"ask_caller_{rc}_{c}"] = (ag.name, "hs")
            self.rules.append(Rule(f"ask_tasks_{rc}_{c}",
                                   [*head, *prem, *no_alt, *req, *decide, q("!retask K1 C1 Tk {} F MT tt", snap)],
                                   [*keep, *outs, *req, q("kill Ik (k_retask Tk)")]))
            self.rules.append(Rule(f"ask_caller_{rc}_{c}",
                                   [*head, *prem, *no_alt, *req, *decide, q("!retask K1 C1 Tk {} F MT ff", snap)],
                                   [*keep, *outs, *req, q("cres R Rk1")]))

    def alternative_condition(self, others: list[a.Recipe], cx: "_Ctx") -> S.Expr:
        """Whether one of ``others`` is acceptable in the current situation (4.4: its
        pre-conditions hold), over the cells ``cx`` reads.

        A pre-condition conjunct that calls the functional layer or reads the error context
        (``last_error?``) cannot be decided inside this one step; it is taken as true (the
        recipe selection that follows the switch still checks it). A conjunct that divides by zero
        cannot be evaluated, so it does not hold (``pholds``: false when it has no value), and
        its recipe is not acceptable, as in a recipe's pre-condition check."""
        options = []
        for alt in others:
            conj = [x for e in alt.pre for x in a.conjuncts(e)
                    if not any(True for _ in a.calls(x)) and
                    not any(isinstance(n, a.LastError) for n in a.walk(x))]
            true = form = q("pl (vbool tt)")
            for x in reversed(conj):
                px = self.pexp(x, cx)
                if self.own_divisors(x):
                    px = q("pholds {}", px)
                form = px if form == true else q("pbin o_and {} {}", px, form)
            options.append(form)
        cond = options[0]
        for f in options[1:]:
            cond = q("pbin o_or {} {}", cond, f)
        return cond

    def alternative_rules(self, ag: a.Agent, rc: str, c: str, head: list, keep: list, cond: S.Expr) -> None:
        """The calling-context search at an activation of ``rc`` holding a request of ``c``: it
        reconfigures onto another recipe when one that avoids ``c`` is acceptable now (``cond``)."""
        self.guards[f"ask_alternative_{rc}_{c}"] = (ag.name, "ask")
        self.rules.append(Rule(f"ask_alternative_{rc}_{c}", [*head, q("!peval vnil vnil vnil {} (vbool tt)", cond)],
                               [*keep, q("kill Ik (k_switch {})", c)]))

    # ------------------------------------------------------------ the whole spec
    def compile(self, request: a.Constraint) -> CompiledModel:
        """The whole spec with ``request``: names, tables, rules, the initial context; checked
        item by item on a copy of the framework, then the logic layer's candidates."""
        spec, m = self.spec, self.model
        self.where_cells: dict[str, list[str]] = m.where_cells
        self.field_types = m.field_types
        for ag in spec.agents:
            for td in ag.types:
                if isinstance(td, a.StructType):
                    key = f"{ag.name}::{td.name}"
                    m.structs[key] = [f.name for f in td.fields]
                    self.field_types[key] = {f.name: self.checked.structs[key][f.name] for f in td.fields}
                elif isinstance(td, a.OpaqueType):
                    m.opaques.add(f"{ag.name}::{td.name}")
        self.initial_values()
        o = self.out
        o.append(Comment("\n================================================================ compiled spec"))
        self.declare_names()
        hdr = len(o)   # constraint declarations go here (they are known at the end)
        self.setup_clock()
        self.task_tables()
        o.extend(self.domain_rules())
        for ag in spec.agents:   # recipe bodies
            for t in ag.tasks:
                for r in t.recipes:
                    self.recipe(ag, t, r)
        if self.logic_pres:   # (the logic activation's phase and snapshot, only when a spec needs them)
            o += [decl("h_lq", q("inst -> phase")), decl("lsnap", q("inst -> val -> type"))]
        started = self.start_code()   # initialisers run when the agents start (4.2)
        sent = self.request(request)
        # constraints: identities, predicates, select and final rules
        self.key_hypotheses()
        for c in sorted(self.cst_pexp):
            self.constraint_rules(c)
        self.calling_context_rules()
        decls = []   # (after the constraints' rules: a logic activation calls functions)
        cst_ids = {c: i for i, c in enumerate((c for c in sorted(m.csts) if c not in self.variant_of), start=1)}
        for c in sorted(m.csts):
            decls.append(decl(c, "cst"))
            decls.append(fact(f"id_{c}", "cst_id {} {}", c, cst_ids[self.variant_of.get(c, c)]))
        decls += [decl(fc, "fn") for fc in sorted(m.functions)]
        o[hdr:hdr] = decls
        if self.crashes:
            o.extend(self.crash_declarations(sum(len(ag.tasks) for ag in spec.agents)))
        if self.clock:
            o.extend(self.time_declarations())
        # the predicate of each constraint, for the calling-context search (framework: retask)
        o.extend(fact(f"cpred_{c}", "cpred {} {}", c, p) for c, p in sorted(self.cst_pexp.items()))
        self.guard_crashed()
        # the statement rules: site ppN_kind has rules stN_kind[_false|_wake|...]
        by_num = self.sites_by_number()
        shown = None
        for r in self.rules:
            site = by_num.get(r.name.split("_", 1)[0]) if r.name.startswith("pp") else None
            if site is not None:
                r.name = "st" + r.name[2:]
                m.rule_sites[r.name] = site
                r.pos = m.sites[site].pos
                if site != shown:   # (for people reading the printed model: where the rules come from)
                    o.append(Comment(self.site_comment(m.sites[site])))
                shown = site
            o.append(r.item())
        # functions and outcomes
        if self.functional == "abstract":
            for fc, (owner, name, rty) in sorted(self.pending_fns.items()):
                o.extend(self.outcome_rules(fc, owner, name, rty))
        start = self.initial_context(started, sent)
        m.init = format_term(start)
        failed_item: list = []
        try:
            sig = extend_framework([x for x in o if not isinstance(x, Comment)], "<compiled model>", failed_item)
        except RoarError as exc:
            raise self.located(exc, failed_item) from None
        # the logic layer: candidates of every predicate, by proof search (8.2)
        # (the initial context last: `roar-verify clf` runs the printed model's #exec once every
        # table it reads is declared)
        rest = self.candidates(sig) + [Comment("\nthe initial context"), exec_(start)]
        m.items = tuple(o + rest)
        m.spec_text = format_items(m.items)
        m.text = framework_text() + m.spec_text
        m._program = Program(extend_signature(sig, [x for x in rest if not isinstance(x, Comment)],
                                              "<compiled model>"))
        return m

    @staticmethod
    def site_comment(site: Site) -> str:
        where = ".".join(x for x in (site.agent, site.task, site.recipe) if x)
        at = f" (line {site.pos.line}, column {site.pos.col})" if site.pos is not None else ""
        return f"st{site.const[2:]} (site {site.const}): {where}: {site.text}{at}".replace("\n", " ")

    def declare_names(self) -> None:
        """One constant per agent, variable (a cell), task (with its identity number) and recipe."""
        m, o = self.model, self.out
        ids = 0
        for ag in self.spec.agents:
            m.agents[f"a_{ag.name}"] = ag.name
            o.append(decl(f"a_{ag.name}", "agent"))
            for v in ag.vars:
                c = self.cell(ag.name, v.name)
                m.cell_types[c] = self.checked.var_types.get((ag.name, v.name))
                o.append(decl(c, "dest"))
            for t in ag.tasks:
                ids += 1
                tc = self.task_c(ag.name, t.name)
                m.tasks[tc] = (ag.name, t.name)
                o.append(decl(tc, "task"))
                o.append(fact(f"id_{tc}", "task_id {} {}", tc, ids))
                for r in t.recipes:
                    rc = self.recipe_c(ag.name, t.name, r.name)
                    m.recipes[rc] = (ag.name, t.name, r.name)
                    o.append(decl(rc, "recipe"))

    def task_tables(self) -> None:
        """The tables of each task the logic layer reads: pre-conditions (symbolic, or evaluated by
        the logic activation when they call a function), post-conditions, the tasks it masks
        (4.3, incompatible tasks), its recipes."""
        m, o = self.model, self.out
        incompatible = incompatible_tasks(self.checked)
        for ag in self.spec.agents:
            for t in ag.tasks:
                tc = self.task_c(ag.name, t.name)
                pcx = _Ctx(self, ag, [], snapshot=True)
                pcx.task, pcx.recipe, pcx.purpose = t.name, "", "post"
                qualified = [self._qualify(e, ag.name) for e in t.pre]
                # a pre-condition that calls a function is split into its conjuncts: those that call
                # one are evaluated by the logic activation, the others are ordinary (sub-goaled)
                qualified = [x for e in qualified
                             for x in (a.conjuncts(e) if any(True for _ in a.calls(e)) else [e])]
                pres = [self.pexp(e, pcx) if not any(True for _ in a.calls(e)) else self.logic_pre(ag, t, e)
                        for e in qualified]
                # a pre-condition on another agent's variables is planned by this agent on its own
                # tasks only: it has a key of its own (the same predicate sent to its owner as a
                # constraint is planned there, on the owner's tasks)
                pres = [q("pown {} {}", f"a_{ag.name}", p)
                        if any(isinstance(r, a.Remote) and r.agent != ag.name for r in a.refs(e))
                        and not self.calls_function(p) else p
                        for p, e in zip(pres, qualified)]
                for p, cond in zip(pres, qualified):
                    self.predicates[p] = ag.name
                    self.predicate_exprs.setdefault(p, (ag, cond))
                o.append(fact(f"tpre_{tc}", "tpre {} {}", tc, vlist([q("vpexp {}", p) for p in pres])))
                others = incompatible.get((ag.name, t.name), [])
                if others:
                    m.incompatible[(ag.name, t.name)] = list(others)
                o.append(fact(f"incompat_{tc}", "incompat {} {}", tc,
                              vlist([q("vtsk {}", self.task_c(ag.name, u)) for u in others])))
                for i, e in enumerate(t.post):
                    for conj in a.conjuncts(e):
                        o.append(fact(f"post_{tc}_{i}_{len(o)}", "post {} (fatom {})", tc,
                                      self.pexp(self._qualify(conj, ag.name), pcx)))
                rcs = [q("vrcp {}", self.recipe_c(ag.name, t.name, r.name)) for r in t.recipes]
                o.append(fact(f"recipes_{tc}", "recipes {} {}", tc, vlist(rcs)))

    def request(self, request: a.Constraint) -> tuple:
        """The request from outside: its constraint (a variant when its where clause is one no
        recipe sends) and its where values; what :meth:`initial_context` sends."""
        m = self.model
        top = self.spec.agent(request.target())
        req_cst = self.cst_for(top, request.expr, top.name, purpose="request")
        m.request_cst, m.request_agent = req_cst, top.name
        writes = request.writes()
        cells = [self.cell(top.name, w) for w in writes]
        req_cst = self.where_cst(req_cst, cells)   # (a where clause its recipes do not use: a variant)
        m.request_cst = req_cst
        values = [self.request_value(v) for v in writes.values()]
        self.note_where_hyps(req_cst, cells, values)
        return top, req_cst, cells, [self.const_value(v) for v in values]

    def initial_context(self, started: Optional[list], sent: tuple) -> S.Expr:
        """The initial context: the failure budgets, every agent's empty mask and cells with their
        initial values, the clock, the crash plan, the start code, and the request ``r0``."""
        top, req_cst, cells, wvals = sent
        init = [q("fails_left {} {}", fc, nat(k)) for fc, k in sorted(self.failure_budgets.items())]
        for ag in self.spec.agents:
            init.append(q("mask {} vnil", f"a_{ag.name}"))
            for v in ag.vars:
                c = self.cell(ag.name, v.name)
                init.append(q("contains {} {}", c, self.initial(ag, v)))
        failed, gate = q("vnil"), q("rs r0 s_sent")
        if self.clock:
            init += [q("clock 0"), q("tmrs vnil")]
        if self.crashes:
            init.extend(self.crash_init())
            if top.name in self.crash_agents:   # sent in epoch 0
                failed = q("vcons (vtsk t_ep0) vnil")
            if not self.crashes.scheduled:       # the crash plan is decided first (crash_plan_...)
                gate = q("cgate z r0")
        if started:   # the agents start first: their initialisers that call the functional layer
            init += started
            gate = q("sgate r0")
        init += [q("rq r0 {} {} itop k_make", f"a_{top.name}", req_cst), gate, q("ppz r0 ff"),
                 q("hs r0 h_select vnil {} vnil (vsome {})", failed,
                   vlist([q("vpair (vcell {}) {}", c, v) for c, v in zip(cells, wvals)]))]
        return S.Exists(BUILT, "r0", None, tensor(init))

    def located(self, exc: RoarError, failed: list) -> RoarError:
        """A declaration the compiler built that does not check is a bug of the compiler, not of
        the spec; the error points at the spec's statement the declaration was compiled from
        (its site), with the declaration, so the report says where to look."""
        if not failed or not isinstance(failed[0], S.Decl):
            return exc
        decl_ = failed[0]
        site = self.model.site_of_rule(decl_.name)
        where = f"{site.kind} {site.text!r}" if site is not None else f"declaration {decl_.name!r}"
        return RoarError(f"internal error: the CLF compiled for {where} does not check: {exc.message}",
                         site.pos if site is not None else None,
                         notes=[f"<compiled model>: {format_items([decl_]).strip()}",
                                "this is a bug of roar-verify's compiler, not of the spec: please report it"])

    # ------------------------------------------------------------ crashes (opt-in)
    def stamp(self, target: str) -> tuple[list, list, S.Expr]:
        """A request sent to ``target`` carries the target's epoch as the last entry of its
        failed-task list (no plan uses the sentinel task): (premises, conclusions, failed-task list)."""
        if target not in self.crash_agents:
            return [], [], q("vnil")
        epoch = q("cep {} {}", f"a_{target}", f"Cep_{target}")
        return [epoch], [epoch], q("vcons (vtsk {}) vnil", f"Cep_{target}")

    def crash_declarations(self, ids: int) -> list:
        """The epoch sentinels of the agents that may crash (up in even epochs, down in odd
        ones), their tables, and the crash plan decided at the start (exploration)."""
        cr = self.crashes
        top = 2 * cr.bound
        out: list = [Comment("\ncrashes (opt-in): the rules, epochs, the crash plan (docs/semantics.md, Crashes)"),
                     *parsed_part(CRASH_RULES_TEXT, "<framework: crashes>")]
        if self.logic_pres:
            out += parsed_part(CRASH_LOGIC_TEXT, "<framework: crashes and the logic activation>")
        for k in range(top + 1):
            self.model.epochs[f"t_ep{k}"] = k
            out.append(decl(f"t_ep{k}", "task"))
            out.append(fact(f"id_t_ep{k}", "task_id {} {}", f"t_ep{k}", ids + 1 + k))
        out += [fact(f"epu_{k}", "ep_up {}", f"t_ep{k}") for k in range(0, top + 1, 2)]
        out += [fact(f"epn_{k}", "ep_next {} {}", f"t_ep{k}", f"t_ep{k + 1}") for k in range(top)]
        out += [fact(f"eps_{f}_{c}", "ep_stale {} {}", f"t_ep{f}", f"t_ep{c}") for c in range(top + 1)
                for f in range(c + 1) if f < c or c % 2 == 1]
        if not cr.scheduled:
            # which agents may crash is decided before anything else happens, each once: an
            # armed agent's crash is then a step of its own fairness group (weak fairness makes
            # it happen), and a run in which it never crashes is the run of the other branch
            n = len(cr.agents)
            for i, ag in enumerate(cr.agents):
                nxt = q("rs R s_sent") if i == n - 1 else q("cgate {} R", nat(i + 1))
                out.append(Rule(f"may_crash_a_{ag}", [q("cgate {} R", nat(i))], [q("carmed {}", f"a_{ag}"), nxt]).item())
                out.append(Rule(f"never_crash_a_{ag}", [q("cgate {} R", nat(i))], [nxt]).item())
        # neither a crash nor a comeback is a step of the agent itself
        self.model.fair_outcomes.update({"crash": "crash", "back": "coming back", "back_armed": "coming back"})
        return out

    def crash_init(self) -> list:
        cr = self.crashes
        init = [q("cleft {}", nat(cr.bound))] + [q("cep {} t_ep0", f"a_{ag}") for ag in cr.agents]
        if cr.scheduled:
            init += [q("carmed {}", f"a_{ag}") for ag in cr.agents]
        return init

    def guard_crashed(self) -> None:
        """With crashes, every compiled rule of an agent that may crash needs the request it
        serves to be of the agent's current epoch, with the agent up (``ep_cur``): a crashed agent
        decides, checks and runs nothing, and what it was doing stays stopped after it comes back
        (the framework's ``crash_stop_*`` and ``unavailable*`` rules clean it up)."""
        if not self.crash_agents:
            return
        by_num = self.sites_by_number()
        start = {by_num[x.split("_", 1)[0]] for x in self.start_sites}
        lq_handler = q("h_lq I")
        for rule in self.rules:
            c = by_num.get(rule.name.split("_", 1)[0]) if rule.name.startswith("pp") else None
            if c in start:
                continue   # (the start: before any request, so before any crash)
            if c is not None:
                site = self.model.sites[c]
                agent = site.agent
                reads_lq = any(head_of(p) == "hs" and args_of(p)[1] == lq_handler for p in rule.premises)
                how = ("chk" if site.kind == "pre" else "chkcall" if site.const in self.checker_sites
                       else ("hs" if reads_lq else "lq") if site.const in self.logic_sites else "act")
            elif rule.name in self.guards:
                agent, how = self.guards[rule.name]
            else:
                continue
            if agent not in self.crash_agents:
                continue
            v = f"Cep_{agent}"
            prem = []
            if how in ("hs", "chk"):       # the rule reads the request's handler (failed tasks F)
                fl = "F"
            elif how == "ask":             # the activation Ik of the calling context, of request Rk1
                prem.append(q("hs Rk1 Phg ECg Fg Plg Wg"))
                fl = "Fg"
            elif how == "lq":              # the logic activation I, deciding on request Rg
                prem.append(q("hs Rg (h_lq I) ECg Fg Plg Wg"))
                fl = "Fg"
            elif how == "chkcall":
                prem += [q("chk I Rg Rcg Ng"), q("hs Rg Phg ECg Fg Plg Wg")]
                fl = "Fg"
            else:                          # a recipe activation: its request's handler
                if not any(head_of(p) == "act" and args_of(p)[:4] == [q(x) for x in ("I", "R0", "T0", "Rc0")]
                           for p in rule.premises):
                    prem.append(q("act I R0 T0 Rc0 Ng"))
                prem.append(q("hs R0 Phg ECg Fg Plg Wg"))
                fl = "Fg"
            outs = list(prem)
            epoch = q("cep {} {}", f"a_{agent}", v)
            if not rule.has_premise(epoch):
                prem.append(epoch)
                outs.append(epoch)
            prem.append(q("!ep_cur {} {}", fl, v))
            rule.premises += prem
            rule.conclusions += outs

    def const_value(self, e: a.Expr) -> S.Expr:
        if isinstance(e, a.IntLit):
            return q("vnum {}", e.value)
        if isinstance(e, a.DoubleLit):
            return q("vnum {}", num_tree(Fraction(repr(e.value))))
        if isinstance(e, a.BoolLit):
            return q("vbool tt") if e.value else q("vbool ff")
        if isinstance(e, a.StringLit):
            return q("vstr {}", string(e.value))
        if isinstance(e, a.Unary) and e.op == "-" and isinstance(e.operand, (a.IntLit, a.DoubleLit)):
            v = e.operand.value
            return q("vnum {}", num_tree(-Fraction(repr(v)) if isinstance(v, float) else -v))
        raise UnsupportedError(f"a request's where value must be a literal, not '{format_expr(e)}'", e.pos)

    def request_value(self, e: a.Expr) -> a.Expr:
        """A where value of the request from outside: a literal, or a constant expression (no
        variable, no call), evaluated here as an initial value is (:func:`_fold`) and given as the
        literal of its value."""
        if self.literal(e) is not None:
            return e
        for n in a.walk(e):
            if isinstance(n, (a.Name, a.Remote, a.Call)):
                why = (f"calls '{n.qualified}', and a request from outside has no functional layer to call"
                       if isinstance(n, a.Call) else
                       f"reads '{format_expr(n)}', and a request from outside has no agent's variables to read")
                raise UnsupportedError(
                    f"a request's where value must be a constant expression (literals and operators); "
                    f"'{format_expr(e)}' {why}: write its value", n.pos)
        what = f"the request's where value '{format_expr(e)}'"
        v = _fold(e, {}, self.checked, what, self.model.structs)
        if isinstance(v, bool):
            return a.BoolLit(v, pos=e.pos)
        if isinstance(v, str):
            return a.StringLit(v, pos=e.pos)
        if isinstance(v, Fraction) and self.checked.type_of(e) == "int":
            return a.IntLit(int(v), pos=e.pos)
        if isinstance(v, Fraction) and Fraction(repr(float(v))) == v:
            f = float(v)
            return a.DoubleLit(f, pos=e.pos) if f >= 0 else a.Unary("-", a.DoubleLit(-f, pos=e.pos), pos=e.pos)
        raise UnsupportedError(f"{what} is {v}, which has no exact decimal form (the model writes where values "
                               f"as decimal numbers)", e.pos)

    def initial(self, ag: a.Agent, v: a.Var) -> S.Expr:
        ty = self.checked.var_types.get((ag.name, v.name))
        if v.init is None or ag.reading_task(v) is not None:
            return self.default(ty)
        if self.literal(v.init) is not None:   # (a literal: its text, as it always was)
            return self.const_value(v.init)
        got = self.init_values.get((ag.name, v.name))
        return self.default(ty) if got is None else got   # None: written when the agent starts

    # ------------------------------------------------------------ initial values (4.2)
    def initial_values(self) -> None:
        """The initial value of every variable whose initialiser is neither a literal nor a
        task: a constant expression (literals, operators, and the agent's own variables declared
        before it whose initial values are constant) is evaluated here, with the spec's
        expression semantics (:func:`_fold`); one that calls the functional layer, or reads a
        variable initialised so, is evaluated when the agent starts (:meth:`start_code`), as
        hyper runs the initialisers. Anything else is refused, located, with the reason."""
        self.init_values: dict[tuple[str, str], Optional[S.Expr]] = {}
        self.started: list[tuple[a.Agent, a.Var]] = []   # evaluated at start, in declaration order
        for ag in self.spec.agents:
            known: dict[str, object] = {}    # variable -> its constant initial value
            late: set[str] = set()           # variables written at start
            order = [v.name for v in ag.vars]
            for v in ag.vars:
                ty = self.checked.var_types.get((ag.name, v.name))
                e = v.init
                if e is None or ag.reading_task(v) is not None:
                    if e is None:
                        known[v.name] = self.default_py(ty)
                    continue
                what = f"the initial value of '{ag.name}::{v.name}'"
                for ref in a.refs(e):
                    owner = ref.agent if isinstance(ref, a.Remote) else ag.name
                    if owner != ag.name:
                        raise UnsupportedError(
                            f"{what} reads '{owner}::{ref.name}', a variable of another agent (agents start "
                            f"in no order the spec gives: an initial value may read only the agent's own "
                            f"variables declared before it)", ref.pos)
                    if ag.reading_task(ref.name) is not None:
                        raise UnsupportedError(
                            f"{what} reads '{ref.name}', whose value is made by running task "
                            f"'{ag.reading_task(ref.name)}' on each read (a task runs only for a request, "
                            f"not when the agent starts)", ref.pos)
                    if order.index(ref.name) >= order.index(v.name):
                        raise UnsupportedError(
                            f"{what} reads '{ref.name}', declared {'at the same place' if ref.name == v.name else 'after it'}"
                            f" (initial values are given in declaration order: a variable may read only the "
                            f"variables declared before it)", ref.pos)
                calls = any(True for _ in a.calls(e))
                if calls or any(r.name in late for r in a.refs(e)):
                    late.add(v.name)
                    self.started.append((ag, v))
                    self.init_values[(ag.name, v.name)] = None
                    continue
                value = _fold(e, known, self.checked, what, self.model.structs)
                try:
                    text = self.value(value, ty)
                except RoarError:   # no decimal form (1.0 / 3.0): the engine computes it at start
                    late.add(v.name)
                    self.started.append((ag, v))
                    self.init_values[(ag.name, v.name)] = None
                    continue
                known[v.name] = value
                self.init_values[(ag.name, v.name)] = text

    def logic_pre(self, ag: a.Agent, t: a.Task, cond: a.Expr) -> S.Expr:
        """A task pre-condition that calls the functional layer: in the tables it is a cell of its
        own, ``lp_AGENT_K``, that only the logic layer's snapshot holds (no ``contains`` fact): its
        value is the condition evaluated, calls and all, by the logic activation that runs before
        each decision on a constraint sent to the agent (:meth:`logic_activation`). Nothing
        entails it (post-conditions call no function), so a false one is never sub-goaled."""
        got = self.logic_pres.setdefault(ag.name, [])
        cell = f"lp_{ag.name}_{len(got) + 1}"
        got.append((cell, cond, t))
        self.out.append(decl(cell, "dest"))
        p = q("pc {}", cell)
        self.predicates[p] = ag.name
        self.predicate_exprs.setdefault(p, (ag, cond))
        return p

    def logic_activation(self, c: str, tag: a.Agent) -> list[str]:
        """The code of the logic activation of constraint ``c`` (sent to ``tag``, whose task
        pre-conditions call the functional layer): per such pre-condition, its calls (each one
        step, answered by the functional layer: a branch per declared outcome in exploration, the
        callable in a run), arguments first, then its evaluation, which pushes its value. Every
        expression is evaluated on the snapshot the decision takes (``lsnap I S``: the agent's
        variables with the where values in place). A failed call makes its pre-condition false
        (as in a recipe's pre-condition check), and so does a division by zero (at the call site
        that evaluates its arguments, or at the pre-condition's site), which also puts the
        division, located, in the request's error context."""
        code: list[str] = []
        spans = []   # per pre-condition: its call sites (with their pushes before them), its end
        divs: list[tuple[str, int, list]] = []   # per site: its pushes, its divisions (site, divisor)
        for cell, pre, t in self.logic_pres[tag.name]:
            cx = _Ctx(self, tag, [], snapshot=True, task=t.name)
            calls: list[tuple[str, int]] = []
            text = f"pre-condition of task {t.name}: {format_expr(pre)}"
            self.logic_calls(pre, cx, calls, divs, text)
            cond = self.pexp(pre, cx)
            s = self.site("lpre", tag, t.name, "", pre.pos, text)
            self.logic_sites.add(s)
            E = cx.envpat()
            self.rules.append(Rule(
                s, [q("ctl I m_run (ccons {} C) {}", s, E), q("rstat I go"), q("lsnap I S"),
                    q("!peval S {} vnil {} X", E, cond)],
                [q("ctl I m_run C (vcons X E)"), q("rstat I go"), q("lsnap I S")]))
            divs.append((s, cx.pushed, [(self.division_site(tag, t.name, "", d, text), self.pexp(d, cx))
                                        for d in self.own_divisors(pre)]))
            code += [x for x, _n in calls] + [s]
            spans.append((calls + [(s, cx.pushed)], len(code)))
        found = {x: (pushed, ds) for x, pushed, ds in divs}
        for calls, end in spans:
            rest = code_list(code[end:])
            for x, pushed in calls:
                E = pushed_env(pushed)
                if not x.endswith("_lpre"):
                    self.rules.append(Rule(f"{x}_false", [q("ctl I (m_call D {}) _ {}", x, E), q("callfail D"),
                                                          q("lsnap I S")],
                                           [q("ctl I m_run {} (vcons (vbool ff) E)", rest), q("lsnap I S")]))
                # a division by zero where the site evaluates: the pre-condition cannot be evaluated,
                # so it is false (its task is unusable for this decision), and the division goes in
                # the request's error context (the located reason if the request then fails)
                for k, (where, d) in enumerate(found[x][1]):
                    self.rules.append(Rule(
                        f"{x}_div{chr(97 + k)}",
                        [q("ctl I m_run (ccons {} C) {}", x, E), q("rstat I go"), q("lsnap I S"), q(HS_LOGIC, "EC"),
                         q("!peval S {} vnil {} (vnum 0)", E, d), q("!ec_add (k_local {}) EC EC1", where)],
                        [q("ctl I m_run {} (vcons (vbool ff) E)", rest), q("rstat I go"), q("lsnap I S"),
                         q(HS_LOGIC, "EC1")]))
        return code

    def logic_calls(self, e: a.Expr, cx: _Ctx, out: list, divs: Optional[list] = None, text: str = "") -> None:
        """The calls of a task pre-condition, arguments first, as sites of the logic activation
        (their arguments evaluated on its snapshot); each pushes its result. ``divs`` gets, per
        call site, the divisions its arguments make (their sites, named in ``text``, and divisors)."""
        if isinstance(e, a.Call):
            for x in e.args:
                self.logic_calls(x, cx, out, divs, text)
            found = self.spec.resolve_function(cx.agent, e)
            if found:
                owner = found[0][0]
                result_ty = self.checked.fn_sigs.get((owner, e.name), (None, None))[0]
            else:
                owner, result_ty = None, a.BUILTINS[e.name][0]
            args = [self.pexp(x, cx) for x in e.args]
            fc = self.fn_c(owner, e.name)
            self.model.fn_types[fc] = result_ty
            self.model.fn_params[fc] = list(self.checked.fn_sigs.get((owner, e.name), (None, []))[1] or [])
            self.pending_fns[fc] = (owner, e.name, result_ty)
            s = self.site("call", cx.agent, cx.task, "", e.pos, format_expr(e), function=e.qualified)
            self.logic_sites.add(s)
            self.model.call_sites.setdefault(fc, []).append(e.pos)
            E = cx.envpat()
            vals = [f"A{i + 1}" for i in range(len(args))]
            self.rules.append(Rule(
                s, [q("ctl I m_run (ccons {} C) {}", s, E), q("rstat I go"), q("lsnap I S"),
                    *(q("!peval S {} vnil {} {}", E, p, v) for p, v in zip(args, vals))],
                [q("pending {} {} d", fc, vlist(vals)), q("ctl I (m_call d {}) C {}", s, E), q("rstat I go"),
                 q("lsnap I S")], fresh=("d",)))
            out.append((s, cx.pushed))
            if divs is not None:
                divs.append((s, cx.pushed, [(self.division_site(cx.agent, cx.task, "", d, text), self.pexp(d, cx))
                                            for x in e.args for d in self.own_divisors(x)]))
            cx.slots[id(e)] = len(cx.env)
            cx.env.insert(0, "")
            cx.pushed += 1
            return
        for ch in e.children():
            if isinstance(ch, a.Expr):
                self.logic_calls(ch, cx, out, divs, text)

    def start_code(self) -> Optional[list]:
        """The initialisers that call the functional layer (or read a variable initialised so),
        run when the agents start, before the request from outside is sent (hyper runs them
        when the agent starts): an activation ``i_start`` of its own runs, in declaration order,
        one ``set`` per such variable (its calls first, as in a recipe: each call is one step,
        answered by the functional layer: the declared outcomes in exploration, so the start
        state branches, the Python callable in a run). A call that fails leaves the variable at
        its type's default. A division by zero in one is an error of the start: the request from
        outside fails at once, not sent, with the division as its error context (the agents cannot
        start: :meth:`division_failures`). The request is sent (``start_done``) when all are done.
        Returns the facts that start it, or None when no variable needs it."""
        if not self.started:
            return None
        code: list[str] = []
        ends: list[tuple[list[str], int]] = []   # per variable: its call sites, where its code ends
        stub_t, stub_r = a.Task("", pos=None), a.Recipe("", pos=None)
        for ag, v in self.started:
            st = a.Set(a.Name(v.name, pos=v.pos), v.init, pos=v.init.pos)
            # (a division by zero in it: the agents cannot start, division_failures)
            self.starting = f"initial value of {ag.name}::{v.name}: {format_expr(v.init)}"
            sites = self.stmt(ag, stub_t, stub_r, st, [])
            self.starting = None
            for x in sites:
                self.start_sites.add(x)
                self.model.sites[x].text = (f"initial value of {ag.name}::{v.name}: {format_expr(v.init)}"
                                            if self.model.sites[x].kind == "set" else self.model.sites[x].text)
            code += sites
            ends.append(([x for x in sites if self.model.sites[x].kind == "call"], len(code)))
        for calls, end in ends:
            rest = code_list(code[end:])
            for x in calls:   # a failed call: the variable keeps its default, the next one starts
                self.rules.append(Rule(f"start_failed_{x[2:]}", [q("ctl i_start (m_call D {}) _ _", x), q("callfail D")],
                                       [q("ctl i_start m_run {} vnil", rest)]))
        sent = q("cgate z R") if self.crashes and not self.crashes.scheduled else q("rs R s_sent")
        self.rules.append(Rule("start_done", [q("ctl i_start m_run cnil vnil"), q("rstat i_start go"), q("sgate R")],
                               [sent]))
        self.out += [decl("i_start", "inst"), decl("sgate", q("req -> type"))]
        return [q("ctl i_start m_run {} vnil", code_list(code)), q("rstat i_start go")]

    def default_py(self, ty: Optional[str]):
        """A type's default as a Python value (:func:`_fold`'s values)."""
        if ty in ("int", "double"):
            return Fraction(0)
        if ty == "bool":
            return False
        if ty in ("string", "identifier") or ty is None:
            return ""
        fields = self.model.structs.get(ty)
        if fields is not None:
            return tuple(self.default_py(self.field_types[ty][f]) for f in fields)
        return _Opaque(0)

    def snapshot_cells(self, c: str) -> list[str]:
        """The cells a decision on ``c`` reads: the predicate's, and those its target's task pre-
        and post-conditions read."""
        tag, pred = self.cst_ast[c]
        cells: list[str] = []

        def add(e):
            for ref in a.refs(e):
                owner = tag.name if isinstance(ref, a.Name) else ref.agent
                cell = self.cell(owner, ref.name)
                if cell not in cells:
                    cells.append(cell)
        add(self._qualify(pred, tag.name))
        for t in tag.tasks:
            for e in t.pre:
                add(self._qualify(e, tag.name))
            for e in t.post:   # hypotheses (candidates) are made of post-condition and predicate sides
                add(self._qualify(e, tag.name))
        return cells

    def constraint_rules(self, c: str) -> None:
        tag, pred = self.cst_ast[c]
        # the snapshot: variables of the agent its tasks' pre-conditions read, and the predicate's
        cells = self.snapshot_cells(c)
        where = self.where_cells.get(c, [])
        for w in where:
            if w not in cells:
                cells.append(w)
        vars_ = {cell: f"V{i + 1}" for i, cell in enumerate(cells)}
        wvars = {cell: f"W{i + 1}" for i, cell in enumerate(where)}
        for prefix in ("select_", "reselect_", "final_", "ensure_broken_", "ensure_broken_top_", "ensure_check_"):
            self.guards[prefix + c] = (tag.name, "hs")
        pred_p = self.cst_pexp[c]
        rq = q("rq R {} {} J K", f"a_{tag.name}", c)
        mask = f"a_{tag.name}"

        def snap(values):
            return vlist([q("vpair (vcell {}) {}", cell, values[cell]) for cell in cells])
        reads = [q("contains {} {}", cell, v) for cell, v in vars_.items()]
        back = list(reads)
        # first selection: the logic layer decides with the where values in place of the
        # variables they write; an accepted constraint writes them (framework: where_write)
        newv = dict(vars_)
        newv.update(wvars)
        wl = vlist([q("vpair (vcell {}) {}", w, wvars[w]) for w in where])
        # the decision records the tree it commits as the handler's plan at once (an abort that came
        # before tasks_chosen would leave it in the mask: framework, `committed`)
        plan = q("!committed D Pl1")
        # a division by zero in the predicate: it cannot be evaluated (its rules below would be
        # disabled); per divisor, where the predicate is evaluated, a rule that fires when the divisor
        # is 0 and gives the located reason: the decision fails the request, the final check finds
        # the constraint violated, a held ensure is broken (each with the division in the error
        # context); see constraint_divisions
        zeros = self.constraint_divisions(c)
        if tag.name in self.logic_pres:
            self.logic_select(c, tag, rq, reads, back, snap(newv), snap(vars_), wl, pred_p)
        else:
            zero, ec = self.pre_division_premise(tag, snap(newv))
            self.rules.append(Rule(
                f"select_{c}",
                [q("hs R h_select EC F Pl (vsome {})", wl), q("rs R s_pending"), rq, q("mask {} M", mask), *reads,
                 q("!mtasks M MT"), q("!decide_k K {} {} F MT D", pred_p, snap(newv)), *zero,
                 q("!commit D R M M1"), plan],
                [q("hs R (h_dec D) {} F Pl1 (vsome {})", ec, wl), q("rs R s_pending"), rq, q("mask {} M1", mask),
                 *back]))
            zero, ec = self.pre_division_premise(tag, snap(vars_))
            self.rules.append(Rule(
                f"reselect_{c}",
                [q("hs R h_select EC F Pl vnone"), rq, q("mask {} M", mask), *reads,
                 q("!mtasks M MT"), q("!decide_k K {} {} F MT D", pred_p, snap(vars_)), *zero,
                 q("!commit D R M M1"), plan],
                [q("hs R (h_dec D) {} F Pl1 vnone", ec), rq, q("mask {} M1", mask), *back]))
        self.rules.append(Rule(
            f"final_{c}", [q("hs R h_final EC F Pl W"), rq, *reads,
                           q("!peval {} vnil vnil {} (vbool B)", snap(vars_), pred_p)],
            [q("hs R (h_verdict B) EC F Pl W"), rq, *back]))
        # a held ensure is re-checked (4.4, 5.2): when its predicate stops holding, the request
        # goes to temporary failure with the breach in its error context, its tasks are released,
        # it decides again, and its emitter pauses meanwhile (figure 3); timed, at its period
        breach = [q("!peval {} vnil vnil {} (vbool ff)", snap(vars_), pred_p), q("!ec_broke {} EC EC1", c)]
        if c in self.eperiods:
            self.timed_ensure_check(c, tag, reads, back, snap(vars_), pred_p)
        if c in self.eperiods or c in self.ensured:
            self.broken_rules(c, tag, reads, back, breach, "")
        for k, (site, d) in enumerate(zeros):
            self.division_decisions(c, tag, k, site, d, rq, reads, back, snap(newv), snap(vars_), wl)

    def constraint_divisions(self, c: str) -> list[tuple[str, str]]:
        """The divisions of constraint ``c``'s predicate: per divisor, the site naming it and the
        divisor as a pexp over the snapshot."""
        tag, pred = self.cst_ast[c]
        pcx = _Ctx(self, tag, [], snapshot=True)
        return [(self.division_site(tag, "", "", d, f"constraint {self.model.csts[c][1]}"), self.pexp(d, pcx))
                for d in self.own_divisors(pred)]

    def pre_division_premise(self, tag: a.Agent, snapshot: S.Expr) -> tuple[list, str]:
        """The premises a decision on a constraint sent to ``tag`` adds when ``tag``'s task
        pre-conditions divide (:meth:`pre_divisions`), and the error context it leaves: a decision
        that finds no task puts the first of those divisions whose divisor is 0 on ``snapshot`` in
        the request's error context (framework: ``dec_zero``, ``ec_opt``), the located reason when
        the request then fails. ([], "EC") when they do not divide."""
        pres = self.pre_divisions(tag)
        if not pres:
            return [], "EC"
        divs = vlist([q("vpair (vpexp {}) (vsite {})", d, w) for w, d in pres])
        return [q("!dec_zero D {} {} O", snapshot, divs), q("!ec_opt O EC EC1")], "EC1"

    def pre_divisions(self, ag: a.Agent) -> list[tuple[str, str]]:
        """The divisions of ``ag``'s task pre-conditions that the decision's search evaluates (those
        without a call: the logic activation evaluates the others), in declaration order: per
        divisor, the site naming it and the divisor as a pexp over the snapshot. The search counts a
        pre-condition it cannot evaluate as unmet and not plannable (framework: ``um_noval``), so
        its task is not usable for the decision."""
        known = self.__dict__.setdefault("pre_divs", {})
        if ag.name not in known:
            pcx = _Ctx(self, ag, [], snapshot=True)
            got = []
            for t in ag.tasks:
                for e in t.pre:
                    calls = any(True for _ in a.calls(e))
                    for conj in (a.conjuncts(e) if calls else [e]):
                        if any(True for _ in a.calls(conj)):
                            continue
                        text = f"pre-condition of task {t.name}: {format_expr(conj)}"
                        got += [(self.division_site(ag, t.name, "", d, text), self.pexp(self._qualify(d, ag.name), pcx))
                                for d in self.own_divisors(conj)]
            known[ag.name] = got
        return known[ag.name]

    def division_decisions(self, c: str, tag: a.Agent, k: int, where: str, d: S.Expr, rq: S.Expr,
                           reads: list, back: list, snap_w: S.Expr, snap: S.Expr, wl: S.Expr) -> None:
        """The rules of :meth:`constraint_rules` for a divisor ``d`` of ``c``'s predicate that is 0
        (site ``where``): the decision (``select_cN``, ``reselect_cN``; with a logic activation, the
        decision after it) fails the request, as when there is no task (4.3: the constraint cannot
        be decided), the final check gives the verdict false (the constraint is not established),
        and a held ensure is broken (:meth:`broken_rules` with the division as the breach). Each
        adds the division to the error context."""
        n = chr(97 + k)
        ec = q("!ec_add (k_local {}) EC EC1", where)
        fail = [q("rs R s_failure"), q("ecf R EC1"), rq]
        names = [f"select_{c}_div{n}"]
        if tag.name in self.logic_pres:
            # (the predicate reads no pre-condition cell: the snapshot the logic activation took)
            self.rules.append(Rule(
                names[-1], [q(HS_LOGIC, "EC"), q("lsnap I S"), q("ctl I m_run cnil _"), q("rstat I go"), rq,
                            q("rs R _"), q("!peval S vnil vnil {} (vnum 0)", d), ec], fail))
        else:
            self.rules.append(Rule(
                names[-1], [q("hs R h_select EC F Pl (vsome {})", wl), q("rs R s_pending"), rq, *reads,
                            q("!peval {} vnil vnil {} (vnum 0)", snap_w, d), ec], [*fail, *back]))
            names.append(f"reselect_{c}_div{n}")
            self.rules.append(Rule(
                names[-1], [q("hs R h_select EC F Pl vnone"), q("rs R _"), rq, *reads,
                            q("!peval {} vnil vnil {} (vnum 0)", snap, d), ec], [*fail, *back]))
        names.append(f"final_{c}_div{n}")
        self.rules.append(Rule(
            names[-1], [q("hs R h_final EC F Pl W"), rq, *reads, q("!peval {} vnil vnil {} (vnum 0)", snap, d), ec],
            [q("hs R (h_verdict ff) EC1 F Pl W"), rq, *back]))
        if c in self.eperiods or c in self.ensured:
            names += self.broken_rules(c, tag, reads, back,
                                       [q("!peval {} vnil vnil {} (vnum 0)", snap, d),
                                        q("!ec_add (k_local {}) EC EC0", where), q("!ec_broke {} EC0 EC1", c)],
                                       f"_div{n}")
        for x in names:
            self.guards[x] = (tag.name, "hs")

    def logic_select(self, c: str, tag: a.Agent, rq: S.Expr, reads: list, back: list, snap_w: S.Expr,
                     snap: S.Expr, wl: S.Expr, pred_p: S.Expr) -> None:
        """The decision on ``c`` when the target's task pre-conditions call the functional layer
        (4.3 through the functional layer): ``lselect_cN`` / ``lreselect_cN`` take the snapshot
        (the where values in place, as ``select_cN`` does) and start the logic activation that
        makes the calls and evaluates those pre-conditions on it (:meth:`logic_activation`);
        when it is done, ``select_cN`` decides on the same snapshot, each such pre-condition's
        value in its cell ``lp_AGENT_K``."""
        code = code_list(self.logic_activation(c, tag))

        def start(snapshot):
            return [q("lsnap i {}", snapshot), q("ctl i m_run {} vnil", code), q("rstat i go")]
        self.rules.append(Rule(
            f"lselect_{c}", [q("hs R h_select EC F Pl (vsome {})", wl), q("rs R s_pending"), rq, *reads],
            [q("hs R (h_lq i) EC F Pl (vsome {})", wl), q("rs R s_pending"), rq, *back, *start(snap_w)],
            fresh=("i",)))
        self.rules.append(Rule(
            f"lreselect_{c}", [q("hs R h_select EC F Pl vnone"), rq, *reads],
            [q("hs R (h_lq i) EC F Pl vnone"), rq, *back, *start(snap)], fresh=("i",)))
        cells = [cell for cell, _pre, _t in self.logic_pres[tag.name]]
        got = q("vnil")
        full = q("S")
        for i, cell in enumerate(cells):
            got = q("vcons {} {}", f"X{i + 1}", got)
            full = q("vcons (vpair (vcell {}) {}) {}", cell, f"X{i + 1}", full)
        self.guards[f"lselect_{c}"] = self.guards[f"lreselect_{c}"] = (tag.name, "hs")
        zero, ec = self.pre_division_premise(tag, full)
        mask = f"a_{tag.name}"
        self.rules.append(Rule(
            f"select_{c}",
            [q(HS_LOGIC, "EC"), q("lsnap I S"), q("ctl I m_run cnil {}", got), q("rstat I go"), rq, q("mask {} M", mask),
             q("!mtasks M MT"), q("!decide_k K {} {} F MT D", pred_p, full), *zero, q("!commit D R M M1"),
             q("!committed D Pl1")],
            [q("hs R (h_dec D) {} F Pl1 W", ec), rq, q("mask {} M1", mask)]))

    def timed_ensure_check(self, c: str, tag: a.Agent, reads: list, back: list, snap: S.Expr,
                           pred_p: S.Expr) -> None:
        """Timed mode: a held ensure of ``c`` is re-checked at its period (``held_arm`` arms it),
        not at any moment: at its tick it is armed again if its predicate holds (this rule), and
        otherwise it is broken as in the untimed model, its timer gone (:meth:`broken_rules`)."""
        ens = q("rq R {} {} J k_ensure", f"a_{tag.name}", c)
        self.rules.append(Rule(
            f"ensure_check_{c}",
            [q("hs R (h_heldt Dk) EC F Pl W"), ens, *map(q, TIMER_DUE), *reads,
             q("!peval {} vnil vnil {} (vbool tt)", snap, pred_p), q("!eperiod {} Pk", c), q("!tafter Pk Dk Dk2"),
             q("!tm_ins Dk2 Lk1 Lk2")],
            [q("hs R (h_heldt Dk2) EC F Pl W"), ens, q("clock Dk"), q("tmrs Lk2"), *back]))

    def broken_rules(self, c: str, tag: a.Agent, reads: list, back: list, breach: list, suffix: str) -> list[str]:
        """A held ensure of ``c`` is broken (4.4, 5.2) when ``breach`` holds (its predicate false,
        or a division by zero in it): the request goes to temporary failure with the breach in its
        error context (``EC1``), its tasks are released, it decides again, and its emitter pauses
        meanwhile (figure 3; ``ensure_broken_top`` when no activation emitted it). Timed, this is
        its periodic re-check, and its timer goes. Returns the rules' names."""
        ens = q("rq R {} {} J k_ensure", f"a_{tag.name}", c)
        mask = f"a_{tag.name}"
        timed = c in self.eperiods
        held = q("hs R (h_heldt Dk) EC F Pl W") if timed else q("hs R h_held EC F Pl W")
        head = [held, q("rs R s_success"), ens, q("mask {} M", mask), q("!mrm M Pl M1"),
                *([*map(q, TIMER_DUE), q("!clk_norm Lk1 Dk Tk1")] if timed else []), *reads, *breach]
        again = [q("hs R h_select EC1 F vnil vnone"), q("rs R s_tempfail"), ens, q("mask {} M1", mask),
                 *([q("clock Tk1"), q("tmrs Lk1")] if timed else []), *back]
        names = [f"ensure_broken_{c}{suffix}", f"ensure_broken_top_{c}{suffix}"]
        self.rules.append(Rule(
            names[0], [*head, q("rstat J Z"), q("!child_pause Z Z1"), q("act J R0 T0 Rc0 N0"), q("rs R0 S0"),
                       q("!shown Z Z1 S0 S1")],
            [*again, q("rstat J Z1"), q("act J R0 T0 Rc0 N0"), q("rs R0 S1")]))
        self.rules.append(Rule(names[1], [*head, q("!detached J")], again))
        return names

    def outcome_rules(self, fc: str, owner: Optional[str], name: str, rty: Optional[str]) -> list:
        prim = None
        if self.registry is not None:
            prim = self.registry.lookup(name, owner)
        outcomes = prim.outcomes if prim is not None else (
            DEFAULT_OUTCOMES if rty == "bool" else (Outcome("success", True),))
        rules = []
        bound = prim.max_failures if prim is not None else None
        if bound is not None:
            self.failure_budgets[fc] = bound
        for o in outcomes:
            oname = re.sub(r"\W", "_", o.name)
            writes_p, writes_o = [], []
            for var, val in o.writes.items():
                agent, _, vn = var.rpartition("::")
                cell = self.cell(agent or owner, vn)
                writes_p.append(q("contains {} _", cell))
                writes_o.append(q("contains {} {}", cell, self.value(val, self.model.cell_types.get(cell))))
            if o.result is not None:
                res = q("return {} D", self.value(o.result, rty))
            elif rty == "bool":
                res = q("return (vbool tt) D") if o.success else q("return (vbool ff) D")
            elif o.success:
                res = q("return {} D", self.default(rty))
            else:
                res = q("callfail D")
            budget_p, budget_o = [], []
            if bound is not None and not o.success:   # one failure fewer left (an assumption)
                budget_p, budget_o = [q("fails_left {} (s N)", fc)], [q("fails_left {} N", fc)]
            rule = f"outcome_{fc}_{oname}"
            if prim is not None and prim.fair and o.success:   # its own fairness group (strong fairness)
                self.model.fair_outcomes[rule] = f"{f'{owner}::' if owner else ''}{name} -> {o.name}"
            rules.append(Rule(rule, [q("pending {} _ D", fc), *writes_p, *budget_p], [res, *writes_o, *budget_o]).item())
        return rules

    def domain_rules(self) -> list:
        """The agents' rules (``NAME = P, ... |- C, ...;``) as clauses of the entailment ``hyp``
        (4.3: "the rules associated to the domain of the constraint"): each conclusion conjunct
        follows from the premises, each use spending one unit of the proof budget. Capitalised
        names that are not variables of the agent are logic variables over expressions. A rule
        that calls a function or reads ``last_error?`` cannot apply, since constraints and
        post-conditions do not call functions; it is listed in ``CompiledModel.unused_rules``."""
        out = []
        for ag in self.spec.agents:
            own = {v.name for v in ag.vars}
            # a rule is part of its agent's exported domain: it applies to the tasks of the agents
            # that see that agent (itself, its importers, the agents of the same .roar file)
            seers = [b for b in self.spec.agents if ag.name in self.spec.visible(b)]
            scoped = len(seers) < len(self.spec.agents)
            if scoped and ag.rules:
                out.extend(fact(f"scope_{self.task_c(b.name, t.name)}_{ag.name}", "dom_scope {} {}",
                                self.task_c(b.name, t.name), f"a_{ag.name}") for b in seers for t in b.tasks)
            for rule in ag.rules:
                exprs = list(rule.premises) + list(rule.conclusions)
                if any(isinstance(n, (a.Call, a.LastError)) for e in exprs for n in a.walk(e)):
                    self.model.unused_rules.append(f"{ag.name}::{rule.name}")
                    continue
                cx = _Ctx(self, ag, [], snapshot=True)
                for e in exprs:
                    for ref in a.refs(e):
                        if isinstance(ref, a.Name) and ref.name not in own and ref.name[:1].isupper():
                            cx.logic.setdefault(ref.name, f"L{len(cx.logic) + 1}")
                prem = [self.pexp(x, cx) for e in rule.premises for x in a.conjuncts(e)]
                for i, c in enumerate(x for e in rule.conclusions for x in a.conjuncts(e)):
                    concl = q("hyp {} T (fatom {})", q("s N") if prem else q("_"), self.pexp(c, cx))
                    scope = [q("dom_scope T {}", f"a_{ag.name}")] if scoped else []
                    out.append(backward(f"dom_{ag.name}_{rule.name}_{i}", concl,
                                        [*scope, *(q("hyp N T (fatom {})", p) for p in prem)]))
        return out

    def candidates(self, sig) -> list:
        """The logic layer at compile time: which tasks' post-conditions entail each predicate (4.3, 8.2).

        The entailment ``prove`` is the framework's proof search (hyp/prove
        with a step budget); it does not depend on values, so it is run once
        per (predicate, task) here, by the engine's backward chaining, and
        recorded as ``cands`` clauses in declaration order.
        """
        from ..clf.backward import Backward
        budget = nat(PROOF_BUDGET)

        def provable(pairs: list[tuple[str, S.Expr]]) -> list[bool]:
            """Whether ``prove`` succeeds for each (task, formula)."""
            queries = [query(q("prove {} {} {}", budget, tc, form)) for tc, form in pairs]
            prog = Program(extend_signature(sig, queries, "<compiled model>"))
            goals = [d for d in prog.sig.directives if hasattr(d, "goal")]
            # one search for all the queries, 'hyp' goals tabled: only whether a proof exists is
            # asked, and a failing query's transitive chains cost exponentially more untabled
            bw = Backward(prog)
            bw.tabled = TABLED
            out = []
            for d in goals:
                mark, hmark = bw.u.mark(), len(bw.htrail)
                proofs = bw.solve(d.goal)
                try:
                    out.append(next(proofs, None) is not None)
                finally:
                    proofs.close()
                    bw.undo(mark, hmark)
            return out

        found: dict[str, list[str]] = {}
        pending = sorted(self.predicates.items(), key=lambda pa: (key_text(pa[0]), pa[1]))
        while pending:   # hypotheses are predicates too: their candidates are found in a next round
            pairs = [(p, agent, t) for p, agent in pending for t in self.spec.agent(agent).tasks]
            direct = provable([(self.task_c(agent, t.name), self.goal_form(p)) for p, agent, t in pairs])
            for p, _agent, _t in pairs:
                found.setdefault(p, [])
            for (p, agent, t), ok in zip(pairs, direct):
                if ok:
                    found[p].append((t, None))
            # "if there is no direct solution, but a solution under certain hypotheses" (4.3)
            tries = []   # (p, agent, task, hypothesis) for the predicates no task entails directly
            for (p, agent, t), ok in zip(pairs, direct):
                if not found[p] and p not in self.hyp_keys and not self.calls_function(p):
                    # (a where-keyed one keeps its own; a call is never abduced)
                    for h in self.hypotheses(self.predicate_exprs[p], t):
                        tries.append((p, agent, t, h))
            if tries:
                ctx = lambda agent: _Ctx(self, self.spec.agent(agent), [], snapshot=True)
                forms = [(self.task_c(agent, t.name),
                          q("fwith (fatom {}) {}", self.pexp(h, ctx(agent)), self.goal_form(p))) for p, agent, t, h in tries]
                done: set = set()
                for (p, agent, t, h), ok in zip(tries, provable(forms)):
                    if ok and (p, t.name) not in done:
                        done.add((p, t.name))
                        found[p].append((t, h))
            # keep declaration order, direct or under a hypothesis
            pending = []
            for p in list(found):
                agent = self.predicates[p]
                order = {t.name: i for i, t in enumerate(self.spec.agent(agent).tasks)}
                found[p].sort(key=lambda th: order[th[0].name])
                for t, h in found[p]:
                    if h is not None:
                        hp = self.pexp(h, _Ctx(self, self.spec.agent(agent), [], snapshot=True))
                        if hp not in self.predicates:
                            self.predicates[hp] = agent
                            self.predicate_exprs.setdefault(hp, (self.spec.agent(agent), h))
                            pending.append((hp, agent))
        out_lists: dict[str, list[str]] = {}
        for p, got in found.items():
            agent = self.predicates[p]
            items = []
            for t, h in got:
                tc = self.task_c(agent, t.name)
                hs = q("vnil") if h is None else \
                    q("vcons (vpexp {}) vnil", self.pexp(h, _Ctx(self, self.spec.agent(agent), [], snapshot=True)))
                items.append(q("vpair (vtsk {}) {}", tc, hs))
                if h is not None:
                    self.model.hypotheses.setdefault(p, []).append((agent, t.name, format_expr(h)))
            out_lists[p] = items
        for c, key in self.cst_pexp.items():   # for people and tests: each constraint's candidate tasks
            self.model.candidates[c] = [(self.predicates[key], t.name) for t, _h in found.get(key, [])]
            if key in self.model.hypotheses:
                self.model.hypotheses[c] = self.model.hypotheses.pop(key)
        out: list = [Comment("\nthe logic layer's candidates (prove, run by the compiler), each with its hypotheses")]
        for i, p in enumerate(sorted(out_lists, key=key_text)):
            out.append(fact(f"cands_{i}", "cands {} {}", p, vlist(out_lists[p])))
        return out

    @staticmethod
    def calls_function(p: S.Expr) -> bool:
        """Whether predicate key ``p`` is a task pre-condition that calls a function (``pc lp_AGENT_K``,
        :meth:`logic_pre`): nothing entails it, and it is never abduced."""
        return head_of(p) == "pc" and format_term(args_of(p)[0]).startswith("lp_")

    def hypotheses(self, target: tuple, t: a.Task) -> list:
        """Hypotheses under which task ``t`` may entail the predicate (4.3: "a solution under
        certain hypotheses"): for a conjunct ``L == R`` of the predicate and a post-condition
        ``A == B`` of the task sharing a side with it, the missing link of the chain (post
        ``pos == target``, predicate ``pos == 5``: hypothesis ``target == 5``). The shared side
        is a variable; only equalities are abduced, one per candidate, never one between two
        literals."""
        agent, pred = target
        lits = (a.IntLit, a.DoubleLit, a.StringLit, a.BoolLit)
        out = []
        posts = [self._qualify(x, agent.name) for e in t.post for x in a.conjuncts(e)]
        for c in a.conjuncts(pred):
            if not (isinstance(c, a.Binary) and c.op == "=="):
                continue
            for post in posts:
                if not (isinstance(post, a.Binary) and post.op == "=="):
                    continue
                for x, y in ((c.left, c.right), (c.right, c.left)):
                    for u, v in ((post.left, post.right), (post.right, post.left)):
                        if x == u and isinstance(x, (a.Name, a.Remote)) and v != y \
                                and not (isinstance(v, lits) and isinstance(y, lits)):
                            h = a.Binary("==", v, y, pos=c.pos)
                            self.checked.same_type(h, c)
                            if h not in out:
                                out.append(h)
        return out

    def goal_form(self, p: S.Expr) -> S.Expr:
        """What the logic layer proves for predicate key ``p``: its formula, under the where
        hypotheses of a ``pwhere`` key."""
        if self.calls_function(p):   # a pre-condition that calls a function: nothing entails it
            return q("fatom {}", p)
        if p in self.hyp_keys:
            base, hyps = self.hyp_keys[p]
            form = self._form(*self.predicate_exprs[base])
            for h in reversed(hyps):
                form = q("fwith {} {}", h, form)
            return form
        return self._form(*self.predicate_exprs[p])

    def _form(self, agent: a.Agent, e: a.Expr) -> S.Expr:
        """A predicate as a formula of the logic layer: conjunctions split, each conjunct an atom."""
        if isinstance(e, a.Binary) and e.op == "&&":
            return q("fand {} {}", self._form(agent, e.left), self._form(agent, e.right))
        return q("fatom {}", self.pexp(e, _Ctx(self, agent, [], snapshot=True)))


class _Opaque:
    """An opaque value in a constant expression (only the default, handle 0, exists at compile time)."""

    def __init__(self, handle: int):
        self.handle = handle

    def __eq__(self, other):
        return isinstance(other, _Opaque) and other.handle == self.handle

    def __hash__(self):
        return hash(self.handle)


def _engine(name: str, *args):
    """A number operation as the engine's built-in ``name`` computes it (what ``peval``'s
    ``apply_op`` clauses call at run time)."""
    from ..clf.builtins import BUILTINS
    from ..clf.terms import Const
    return BUILTINS[Const(name)].fn(*args)


def _fold(e: a.Expr, known: dict, checked: CheckedSpec, what: str, structs: dict):
    """The value of a constant expression, as the framework's ``peval`` computes it (its operators
    are the engine's built-ins): numbers exact rationals, ``/`` on two ints truncating toward zero,
    both operands of ``&&`` and ``||`` evaluated, ``==`` structural. ``known`` maps the agent's
    earlier variables to their values. A division by zero is a located error."""
    if isinstance(e, a.BoolLit):
        return e.value
    if isinstance(e, a.IntLit):
        return Fraction(e.value)
    if isinstance(e, a.DoubleLit):
        return Fraction(repr(e.value))
    if isinstance(e, a.StringLit):
        return e.value
    if isinstance(e, (a.Name, a.Remote)):
        return known[e.name]
    if isinstance(e, a.Field):
        base = _fold(e.base, known, checked, what, structs)
        return base[structs[checked.type_of(e.base)].index(e.name)]
    if isinstance(e, a.Unary):
        x = _fold(e.operand, known, checked, what, structs)
        return (not x) if e.op == "!" else _engine("num_neg", x)
    if isinstance(e, a.Binary):
        x = _fold(e.left, known, checked, what, structs)
        y = _fold(e.right, known, checked, what, structs)
        op = e.op
        if op == "==":
            return x == y
        if op == "!=":
            return x != y
        if op in ("<", "<=", ">", ">="):
            return {"<": x < y, "<=": x <= y, ">": x > y, ">=": x >= y}[op]
        if op == "&&":
            return x and y
        if op == "||":
            return x or y
        if op == "+":
            return x + y if isinstance(x, str) else _engine("num_add", x, y)
        if op == "-":
            return _engine("num_sub", x, y)
        if op == "*":
            return _engine("num_mul", x, y)
        if op == "/":
            if y == 0:
                raise RoarError(f"{what} divides by zero: '{format_expr(e.right)}' is 0", e.right.pos)
            return _engine("num_idiv" if checked.type_of(e.left) == "int" else "num_div", x, y)
    raise UnsupportedError(f"{what}: '{format_expr(e)}' is not a constant expression", e.pos)


def compile_spec(spec: Union[a.Spec, CheckedSpec], request, registry: Optional[Registry] = None,
                 functional: str = "abstract", crashes: Optional[Crashes] = None,
                 time=None, request_at: Optional[Pos] = None) -> CompiledModel:
    """Compile ``spec`` (as :func:`~roar_formal.roar.spec.load_spec` loaded it, or checked) with
    ``request`` (text or Constraint) to CLF.

    ``functional`` is "abstract" (each primitive's declared outcomes are
    rules: the explorer branches on them) or "python" (pending calls are
    answered by the registry's callables, outside the signature).
    ``crashes`` (docs/semantics.md, "Crashes") and ``time`` ("untimed", the default, "timed" or
    a :class:`Timing`; docs/semantics.md, "Time") are opt-in: without them the model is the one
    compiled without faults or clock, to the byte. ``request_at``: where the request's text is
    written (a job file's ``request = "..."``, a test's line), so that an error inside it is
    reported there rather than at ``<request>``.
    """
    with written_at(REQUEST_TAG, request_at):
        return _compile_spec(spec, request, registry, functional, crashes, time)


#: the name a request given as text is parsed under (see ``compile_spec``'s ``request_at``)
REQUEST_TAG = "<request>"


def _compile_spec(spec, request, registry, functional, crashes, time) -> CompiledModel:
    checked = checked_spec(spec)
    if registry is not None:
        # every call bound, with the right number of arguments (located), in exploration as in a
        # run: a spec with a functional layer whose module leaves a function out would otherwise be
        # explored with made-up outcomes (a number function answering 0), a check of another spec
        registry.resolve(checked.spec)
    req, typed = typed_request(checked, request)
    if req.target() is None:
        raise RoarError("the request must name exactly one agent", req.pos)
    check_crashes(checked.spec, crashes)
    timing = timing_of(time)
    model = _Compiler(checked.with_types(typed), registry, functional, crashes, timing).compile(req)
    model.crashes = crashes if crashes else None
    model.timing = timing
    model.registry = registry
    return model


def check_crashes(spec: a.Spec, crashes: Optional[Crashes]) -> None:
    """Every agent a crash names is an agent of the spec (located at its name in the job file
    when it came from one), named once; the bound is a whole number from 1."""
    if not crashes:
        return
    known = [ag.name for ag in spec.agents]
    where = list(crashes.where) + [None] * (len(crashes.agents) - len(crashes.where))
    what = "--crash" if crashes.scheduled else "[faults] crash" if any(where) else "crash"
    seen: set = set()
    for name, pos in zip(crashes.agents, where):
        if name not in known:
            raise RoarError(f"{what}: unknown agent {name!r}{did_you_mean(name, known)}; the spec's agents: "
                            f"{', '.join(known)}", pos)
        if name in seen and not crashes.scheduled:
            raise RoarError(f"{what}: agent {name!r} named twice", pos)
        seen.add(name)
    b = crashes.bound
    if isinstance(b, bool) or not isinstance(b, int) or b < 1:
        raise RoarError(f"{what}: the number of crashes in a run must be a whole number from 1, not {b!r}",
                        next((p for p in where if p is not None), None))
