"""Simmons' TCA task-tree logic in Z3: the axioms (``axioms``), proof
obligations and their prover (``theorems``, ``prover``), trace checking
(``trace_events``, ``tasktree``, ``check``), task-tree models with the
Ambler's (``model``, ``unroll``, ``window``, ``schedule``, ``metric``), and the
``roar-verify`` commands (``commands``). See docs/tca.md.
"""
