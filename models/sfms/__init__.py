"""SFMS: sparse facial motion structure tokenizer + listening-head predictor (arXiv 2504.05748).

The first runnable implementation; every decision the paper leaves open is a named config field
(:mod:`models.sfms.config`). Entry points: ``build_sfms`` (:mod:`models.sfms.registry`) and the trainers
``dyadbench train sfms-tokenizer`` / ``dyadbench train sfms`` (:mod:`models.sfms.cli`).
"""
