"""Context headroom: a model-free measure of how much the visible history can lower the error (issue #25).

A ridge regression (:mod:`~dyadbench.headroom.ridge`) from features of exactly what the streaming protocol
shows a model (:mod:`~dyadbench.headroom.features`: the partner's motion and speech and the agent's own
speech, of the current turn and of n history turns) to the agent's motion of the current turn, fitted for
n = 0 … 7 on a corpus's train split with its penalty chosen on val (:mod:`~dyadbench.headroom.estimate`),
scored like the benchmark scores models (:mod:`~dyadbench.headroom.scores`) and reported as tables and a
plot (:mod:`~dyadbench.headroom.report`). ``benchmarks/bench_context_headroom.py`` runs it per corpus.
"""
