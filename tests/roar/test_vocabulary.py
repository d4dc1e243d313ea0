"""The vocabulary's records agree with the framework signature (roar_formal/roar/vocabulary.py).

Every record names the arguments of a family (or a constructor) of
``framework.clf`` in order; the engine stores a fact's implicit arguments
first. So a record's fields must be exactly the declared arguments, implicit
and explicit, and their ``sorts`` the declared types: a framework change that
adds, removes or moves an argument fails here rather than silently decoding
the wrong argument.
"""

from __future__ import annotations

import pytest

from roar_formal.clf.terms import Const, Imp, Pi, Root, Type
from roar_formal.roar import vocabulary as V
from roar_formal.roar.framework import framework_signature

SIG = framework_signature()


def _arguments(classifier) -> tuple[list, object]:
    """The argument types of a classifier (one per Pi or ``->``, implicit ones first) and its target."""
    doms = []
    while isinstance(classifier, (Pi, Imp)):
        if isinstance(classifier, Imp):
            assert classifier.mode == "!", "a family's or constructor's classifier uses only Pi and ->"
        doms.append(classifier.dom)
        classifier = classifier.body
    return doms, classifier


def _sort(t) -> str:
    assert type(t) is Root and isinstance(t.head, Const) and not t.args, f"not a base type: {t}"
    return t.head.name


@pytest.mark.parametrize("name", sorted(V.FACTS))
def test_fact_records_match_the_framework_families(name):
    info = SIG.consts.get(name)
    assert info is not None, f"{name} is not declared in framework.clf"
    assert info.is_family, f"{name} is not a type family"
    rec = V.FACTS[name]
    doms, target = _arguments(info.classifier)
    assert isinstance(target, Type)
    assert len(rec._fields) == len(doms), (
        f"{rec.__name__}{rec._fields} has {len(rec._fields)} fields; framework.clf declares {name} with "
        f"{len(doms)} arguments ({info.implicit} implicit): {info.classifier}")
    assert list(rec.sorts) == [_sort(d) for d in doms], f"{rec.__name__}: the argument types moved"


@pytest.mark.parametrize("name", sorted(V.TERMS))
def test_term_records_match_the_framework_constructors(name):
    info = SIG.consts.get(name)
    assert info is not None and not info.is_family, f"{name} is not a constructor of framework.clf"
    rec = V.TERMS[name]
    doms, _target = _arguments(info.classifier)
    assert len(rec._fields) == len(doms), f"{rec.__name__}{rec._fields} vs {info.classifier}"
    assert list(rec.sorts) == [_sort(d) for d in doms], f"{rec.__name__}: the argument types moved"


@pytest.mark.parametrize("name", sorted(V.WRAPPERS))
def test_wrappers_have_one_argument(name):
    info = SIG.consts.get(name)
    assert info is not None and not info.is_family, f"{name} is not a constructor of framework.clf"
    doms, _target = _arguments(info.classifier)
    assert [_sort(d) for d in doms] == [V.WRAPPERS[name]], f"{name} : {info.classifier}"


def test_explorer_facts_are_not_framework_families():
    # the explorers add them to states; a framework family of the same name would be read as one of them
    for name in V.EXPLORER_FAMILIES:
        assert name not in SIG.consts, f"{name} is declared in framework.clf"


def test_subject_families_are_about_a_request_or_an_activation():
    for names, sort in ((V.REQUEST_FAMILIES, "req"), (V.INSTANCE_FAMILIES, "inst")):
        for name in names:
            info = SIG.consts.get(name)
            if info is None:
                continue   # a compiled spec's family (declared by roar/compile.py), or none
            doms, _target = _arguments(info.classifier)
            assert doms and _sort(doms[0]) == sort, f"{name} : {info.classifier}"


def test_decode_and_decoders_name_the_arguments():
    from roar_formal.clf.terms import const
    f = const("rq", const("r1"), const("a_robot"), const("c_x"), const("itop"), const("k_make"))
    q = V.rq(f)
    assert (q.request.head.name, q.agent.head.name, q.cst.head.name, q.emitter.head.name,
            q.kind.head.name) == ("r1", "a_robot", "c_x", "itop", "k_make")
    assert V.decode(f) == q and type(V.decode(f)) is V.Rq
    assert V.decode(const("unknown_family", const("x"))) is None
    assert V.unwrap(const("vsome", const("vnil"))).head.name == "vnil"
    assert V.head_name(f) == V.RQ
