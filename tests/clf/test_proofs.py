"""Proof terms (--proof): backward proofs as applications, monads as let-chains."""

import re

from roar_formal.clf.program import Program
from roar_formal.clf.query import run_directives, with_big_stack

PERM = """
elem : type. a : elem. b : elem.
list : type. nil : list. cons : elem -> list -> list.
has : elem -> type.
perm : list -> type.
perm_nil : perm nil.
perm_cons : perm (cons X L) o- has X o- perm L.
#query * 2 * 1 has a -o has b -o perm L.
"""

DPS = """
nat : type. z : nat. s : nat -> nat.
dest : type. exp : type.
num : nat -> exp. plus : exp -> exp -> exp.
eval : exp -> dest -> type. return : nat -> dest -> type. addv : nat -> nat -> dest -> type.
ev_num : eval (num N) D -o {return N D}.
ev_plus : eval (plus E1 E2) D -o {Exists d1. Exists d2. eval E1 d1 * eval E2 d2 *
            (Pi V1. Pi V2. return V1 d1 -o return V2 d2 -o {addv V1 V2 D})}.
add_z : addv z N D -o {return N D}.
add_s : addv (s M) N D -o {addv M (s N) D}.
#query * 1 * 1 Pi d. eval (plus (num (s z)) (num z)) d -o {return V d}.
"""


def lines(src, proofs=True):
    out = []
    with_big_stack(run_directives, Program.from_text(src), emit=out.append, proofs=proofs)
    return [l for l in out if l.startswith("Solution")]


def test_backward_proofs_name_the_clauses_and_hypotheses():
    sols = lines(PERM)
    assert sols == ["Solution: \\X1. \\X2. perm_cons (perm_cons perm_nil X1) X2",
                    "Solution: \\X1. \\X2. perm_cons (perm_cons perm_nil X2) X1"]


def test_monadic_proof_is_a_let_chain_using_every_step():
    (sol,) = lines(DPS)
    m = re.fullmatch(r"Solution: \\!d\. \\(X\d+)\. \{(.*) in (X\d+)\}", sol)   # (a Pi's lambda is \!d.)
    assert m, sol
    lets = m.group(2).split(" in ")
    heads = [re.search(r"= (\S+)", l).group(1) for l in lets]
    # ev_plus, two ev_num, the continuation (a variable), add_s, add_z: six steps
    assert heads[0] == "ev_plus" and sorted(heads[1:3]) == ["ev_num", "ev_num"]
    assert re.fullmatch(r"X\d+", heads[3]) and heads[4:] == ["add_s", "add_z"]
    assert " !(s z) !z " in lets[3]   # the continuation's explicit Pi arguments, as Celf prints them
    assert lets[0].endswith(f"ev_plus {m.group(1)}")  # the rule consumed the assumption
    assert lets[-1].startswith(f"let {{{m.group(3)}}}")  # the answer is the last fact made


def test_no_proof_terms_unless_asked():
    assert lines(PERM, proofs=False) == ["Solution: _", "Solution: _"]
