"""The context-headroom estimator (dyadbench.headroom) on toys whose answer is derived by hand.

Toy dialogues of K = 20 one-second turns: the partner holds a random pose u_k ~ N(0, I) for the whole of
turn k (every one of the 56 dims); only speaker1 is evaluated (``agents``), the partner is speaker2. The
agent's expression of turn k is

- history toy: a_k = (1/5) Σ_{d=1..5} u_{k−d} (u before the clip's start is 0), plus frame noise ε,
  σ_ε = 0.01. Only the history holds it: with context n the unseen part Σ_{d=n+1..5} u_{k−d}/5 has variance
  (min(k, 5) − min(k, n))⁺ / 25 per dim, so the error floor averaged over turns k = 0 … 19 is
  n = 0: Σ_k min(k, 5) / (20 · 25) = 85 / 500 = 0.17; n = 3: Σ_k (min(k, 5) − min(k, 3))⁺ / 500 = 31 / 500
  = 0.062; n ≥ 5: σ_ε² = 1e-4;
- current toy: a_k = u_k / 2 + η_k with η_k ~ N(0, 0.5²) per turn, independent of everything visible; the
  history carries nothing, the error floor is 0.25 + σ_ε² at every n.

Jaw and pose of the agent are frame noise only. Speech is quiet white noise (no information).
"""

from __future__ import annotations

import importlib.util
from pathlib import Path

import numpy as np
import pytest

from dyadbench.datasets.base import DyadicClip, InMemorySource, Participant
from dyadbench.headroom.estimate import measure
from dyadbench.headroom.features import MAX_CONTEXT, columns, direction_features
from dyadbench.headroom.report import render
from dyadbench.headroom.ridge import LAMBDAS, Moments, ridge_path
from dyadbench.metrics.dualtalk import SCALE

ROOT = Path(__file__).resolve().parents[1]
TURNS, FPS, RATE, NOISE = 20, 25, 16_000, 0.01
CLIPS = {"train": 60, "val": 20, "test": 20}


def toy_clip(kind: str, split: str, index: int) -> DyadicClip:
    rng = np.random.default_rng([["history", "current"].index(kind), ["train", "val", "test"].index(split), index])
    u = rng.standard_normal((TURNS, 56))
    partner = np.repeat(u, FPS, axis=0)
    if kind == "history":
        padded = np.vstack([np.zeros((5, 56)), u])
        exp = np.stack([padded[k:k + 5, :50].mean(axis=0) for k in range(TURNS)])
    else:
        exp = u[:, :50] / 2 + 0.5 * rng.standard_normal((TURNS, 50))
    agent = np.concatenate([np.repeat(exp, FPS, axis=0), np.zeros((TURNS * FPS, 6))], axis=1)
    agent += NOISE * rng.standard_normal(agent.shape)
    audio = [1e-3 * rng.standard_normal(TURNS * RATE).astype(np.float32) for _ in range(2)]
    return DyadicClip(f"{kind}_{split}_{index:03d}", (
        Participant("speaker1", agent.astype(np.float32), audio[0]),
        Participant("speaker2", partner.astype(np.float32), audio[1])), fps=FPS, sample_rate=RATE,
        agents=("speaker1",))


def toy_split(kind: str, split: str) -> InMemorySource:
    return InMemorySource([toy_clip(kind, split, i) for i in range(CLIPS[split])], dataset=f"toy-{kind}", split=split)


def toy_measure(kind: str, clips: dict[str, int] = CLIPS) -> dict:
    splits = {s: toy_split(kind, s) for s in clips}
    return measure(splits.__getitem__, clips, eval_splits=("test",), seed=0)


@pytest.fixture(scope="module")
def history_result():
    return toy_measure("history")


def raw_mse_exp(result: dict, n: int) -> float:
    return result["splits"]["test"]["means"][str(n)]["mse_exp"] / SCALE["mse_exp"]


def test_history_toy_error_is_the_hand_derived_floor(history_result):
    """n = 0 and n >= 5 at their floors; n = 3 above its floor by at most the estimation error of fitting
    ~150 useful weights on 1200 train turns with a residual of 0.062 (about 0.062 · 150 / 1200 ≈ 0.008)."""
    assert raw_mse_exp(history_result, 0) == pytest.approx(0.17, rel=0.05)
    assert 0.062 <= raw_mse_exp(history_result, 3) <= 0.062 * 1.25
    for n in range(5, MAX_CONTEXT + 1):
        assert raw_mse_exp(history_result, n) < 3 * NOISE ** 2, n
    change = history_result["splits"]["test"]["change"]["7"]["mse_exp"]
    assert change[0] < -0.99 and change[1] <= change[0] <= change[2]


def test_history_is_all_that_lowers_the_error(history_result):
    """Error falls with n up to 5 (each further turn holds part of the target), then stays at the floor."""
    errors = [raw_mse_exp(history_result, n) for n in range(6)]
    assert errors == sorted(errors, reverse=True)


def test_no_history_signal_means_no_gain():
    result = toy_measure("current")
    floor = 0.25 + NOISE ** 2
    for n in range(MAX_CONTEXT + 1):
        assert raw_mse_exp(result, n) == pytest.approx(floor, rel=0.15), n
    change = result["splits"]["test"]["change"]["7"]["mse_exp"][0]
    assert abs(change) < 0.05


def test_measurement_is_deterministic():
    small = {"train": 12, "val": 4, "test": 3}
    assert toy_measure("history", small) == toy_measure("history", small)


def test_ridge_matches_the_normal_equations_solved_directly():
    """Against an independent solve on the standardised data (numpy std, np.linalg.solve), with the history
    columns (from column 4 on) penalised 100 times more; and the moments' SSE against the direct sum."""
    rng = np.random.default_rng(3)
    x = rng.standard_normal((300, 6)) * [1, 2, 3, 0.5, 4, 1] + [0, 1, -2, 3, 0, 5]
    y = x @ rng.standard_normal((6, 2)) + rng.standard_normal((300, 2))
    rows = np.hstack([np.ones((300, 1)), x])
    train = Moments()
    train.add(rows[:200], y[:200])
    lam, ratio = LAMBDAS[3], 100.0
    weights = ridge_path(train, history_from=4, ratio=ratio)[3]
    mu, sd = x[:200].mean(axis=0), x[:200].std(axis=0)
    xs = (x[:200] - mu) / sd
    penalty = lam * np.diag([1, 1, 1, ratio, ratio, ratio])
    w = np.linalg.solve(xs.T @ xs / 200 + penalty, xs.T @ (y[:200] - y[:200].mean(axis=0)) / 200)
    direct = y[:200].mean(axis=0) + ((x[200:] - mu) / sd) @ w
    np.testing.assert_allclose(rows[200:] @ weights, direct, rtol=1e-8, atol=1e-10)
    val = Moments()
    val.add(rows[200:], y[200:])
    np.testing.assert_allclose(val.sse(weights), ((y[200:] - direct) ** 2).sum(axis=0), rtol=1e-8)


def test_rows_use_only_the_turns_a_model_with_context_n_sees():
    """Changing turn k's inputs changes rows of turn k and, for n, of turns k+1 … k+n only."""
    clip = toy_clip("history", "test", 0)
    changed = [p if p.name == "speaker1" else Participant(p.name, p.motion.copy(), p.audio.copy())
               for p in clip.participants]
    k = 8
    changed[1].motion[k * FPS:(k + 1) * FPS] += 1.0
    changed[1].audio[k * RATE:(k + 1) * RATE] *= 50.0
    before = direction_features(clip, "speaker1").rows
    after = direction_features(DyadicClip(clip.clip_id, tuple(changed), fps=FPS, sample_rate=RATE), "speaker1").rows
    for n in (0, 3, MAX_CONTEXT):
        differs = np.flatnonzero(np.any(before[:, :columns(n)] != after[:, :columns(n)], axis=1)) // FPS
        assert sorted(set(differs)) == list(range(k, k + n + 1)), n


def _bench_module(monkeypatch):
    monkeypatch.syspath_prepend(str(ROOT / "benchmarks"))
    spec = importlib.util.spec_from_file_location("bench_context_headroom",
                                                  ROOT / "benchmarks" / "bench_context_headroom.py")
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


def test_result_file_round_trips(history_result, tmp_path, monkeypatch):
    bench = _bench_module(monkeypatch)
    out = tmp_path / "context_headroom"
    data = {"design": bench.design(CLIPS, out.with_suffix(".png")), "corpora": {"toy-history": history_result}}
    argv = ["benchmarks/bench_context_headroom.py", "--datasets", "toy-history"]
    json_path, md_path = bench.write_result(out, render(data), seed=bench.SEED, data=data, argv=argv)
    written = (json_path.read_bytes(), md_path.read_bytes())
    bench.rerender(out)
    assert (json_path.read_bytes(), md_path.read_bytes()) == written
    assert out.with_suffix(".png").read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    text = md_path.read_text()
    assert "toy-history: P-FD exp" in text and "target met" in text
    assert "| 7 | " in text
    assert "Regenerate: `python benchmarks/bench_context_headroom.py --datasets toy-history`" in text


def test_render_of_a_missing_result_is_one_error_line(tmp_path, capsys, monkeypatch):
    with pytest.raises(SystemExit) as exit_info:
        _bench_module(monkeypatch).main(["--render", "--out", str(tmp_path / "nothing")])
    assert exit_info.value.code == 2
    err = capsys.readouterr().err.strip().split("\n")
    assert len(err) == 1 and err[0].startswith("error: ") and "nothing.json" in err[0]
