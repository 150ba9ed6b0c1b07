"""What the embedded corpus design predicts for the baselines (dyadbench.synth.corpus), as checks.

``scores`` maps a model name to its mean raw metrics (suite keys such as ``mse_exp``). Used on a small
generated split (tests/test_baselines.py) and on the committed leaderboard (tests/test_leaderboard.py).
"""

from __future__ import annotations

COMPONENTS = ("exp", "jaw", "pose")
CONSTANT = ("zero", "mean-frame", "median-frame")
VARIED = ("random", "mime", "lagged-mirror", "nn-retrieval")


def corpus_structure_failures(s: dict[str, dict[str, float]]) -> list[str]:
    """Every expectation that does not hold, in words (empty when the structure shows)."""
    failures: list[str] = []

    def expect(ok: bool, what: str) -> None:
        if not ok:
            failures.append(what)

    for c in COMPONENTS:
        for metric in ("fd", "pfd", "mse"):
            expect(abs(s["oracle"][f"{metric}_{c}"]) < 1e-9, f"oracle {metric}_{c} = 0")
        mean = s["mean-frame"][f"mse_{c}"]
        expect(mean <= 1.01 * s["median-frame"][f"mse_{c}"], f"mean-frame mse_{c} <= median-frame (1% slack)")
        expect(2 * mean < s["zero"][f"mse_{c}"], f"mean-frame mse_{c} < zero / 2")
        expect(1.5 * mean < s["random"][f"mse_{c}"], f"mean-frame mse_{c} < random / 1.5")
        expect(abs(s["mime"][f"var_pred_{c}"] - s["mime"][f"var_gt_{c}"]) <= 0.01 * s["mime"][f"var_gt_{c}"],
               f"mime var_pred_{c} = var_gt_{c}")
        expect(s["mime"][f"mse_{c}"] > mean, f"mime mse_{c} > mean-frame")
        for n in CONSTANT:
            expect(s[n][f"var_pred_{c}"] == 0 and s[n][f"div_pred_{c}"] == 0, f"{n} has no variance/diversity ({c})")
    best_constant = min(s[n]["fd_exp"] for n in CONSTANT)
    for n in VARIED:
        expect(s[n]["fd_exp"] < 0.5 * best_constant, f"{n} fd_exp < half the best constant frame's")
    for metric in ("mse_exp", "pfd_exp", "rpcc_exp"):
        expect(s["lagged-mirror"][metric] < s["mime"][metric], f"lagged-mirror {metric} < mime")
        expect(s["nn-retrieval"][metric] < s["random"][metric], f"nn-retrieval {metric} < random")
    return failures
