"""Time to generate a DualTalk-sized synthetic test split (533 dialogues, mean ~31 s), in memory and on disk,
for generator v1 (dataset ``synthetic``) and v2 (``synthetic-v2``) in the same run.

Rows:
- in memory: ``make_clips("test", 533)`` in one process;
- on disk: ``write_dualtalk_split`` (wav + npz + synthetic.json) with ``--jobs 1`` and ``--jobs 2``, v1 and
  v2 (:mod:`dyadbench.synth.writers_v2`); the v2 / v1 ratio of CPU seconds with ``--jobs 1`` is printed
  (goal: at most 1.5);
- reference: the same generator with the speech oscillator written the straightforward way (every
  harmonic an ``np.sin`` over every sample, instead of one wavetable lookup). It runs on the first
  ``--reference-clips`` dialogues and its clips/s is compared with the wavetable's; the max abs audio
  difference between the two oscillators is printed (wavetable lookup vs exact sines).

    python benchmarks/bench_synth.py                 # 533 dialogues
    python benchmarks/bench_synth.py --clips 100     # quick look

Both write benchmarks/results/synth.{json,md} (``--out`` elsewhere).

Goal: the full test split in under 60 s on a 2-core machine. Wall and CPU seconds are both printed: on
a machine shared with other work the wall time stretches, the CPU time does not.
"""

from __future__ import annotations

import os
import platform
import shutil
import sys
import tempfile
from pathlib import Path
from unittest import mock

import click
import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))
from output import RESULTS, Transcript, preformatted, write_result  # noqa: E402  (benchmarks/output.py)
from timing import timed  # noqa: E402  (benchmarks/timing.py)

from dyadbench.synth import speech  # noqa: E402
from dyadbench.synth.corpus import make_clips  # noqa: E402
from dyadbench.synth import writers, writers_v2  # noqa: E402

WRITERS = {"v1": writers.write_dualtalk_split, "v2": writers_v2.write_dualtalk_split}
V2_GOAL = 1.5  # v2 may take at most this many times v1's CPU seconds


def additive_synthesise(r, style, env, f0, vowel, burst, phrases, n_samples, sample_rate):
    """speech._synthesise with the oscillator as a plain sum of sines (same random draws, same signal)."""
    step = sample_rate // speech.FINE_RATE
    audio = speech._noise(r, n_samples) * np.float32(speech.NOISE_FLOOR)
    tables = speech.wavetables(style, sample_rate)
    # harmonic amplitudes of each table: its FFT (the tables are sums of sin(k * phase))
    spectra = [np.fft.rfft(t)[1:] for t in tables]
    n_harm = int(min(40, (0.45 * sample_rate) / style.f0_base))
    for start, end in phrases:
        k0, k1 = int(start * speech.FINE_RATE), min(len(env), int(np.ceil(end * speech.FINE_RATE)) + 1)
        if k1 <= k0:
            continue
        s0, s1 = k0 * step, k1 * step
        inc = f0[k0:k1] / speech.FINE_RATE
        phase0 = (np.cumsum(inc) - inc + r.random()) % 1.0
        frac = np.arange(step) / step
        phase = (phase0[:, None] + inc[:, None] * frac[None, :]).reshape(-1)
        vow = speech.upsample_linear(vowel[k0:k1], step)
        voiced = np.zeros(s1 - s0)
        for k in range(1, n_harm + 1):
            amp_a = -2 * spectra[0][k - 1].imag / speech.TABLE_SIZE
            amp_i = -2 * spectra[1][k - 1].imag / speech.TABLE_SIZE
            voiced += (amp_a + (amp_i - amp_a) * vow) * np.sin(2 * np.pi * k * phase)
        voiced *= speech.upsample_linear(env[k0:k1], step)
        voiced += speech.upsample_linear(burst[k0:k1], step) * speech._noise(r, s1 - s0)
        audio[s0:s1] += (style.loudness * voiced).astype(np.float32)
    return speech.pcm16_to_float(speech.float_to_pcm16(audio))


@click.command()
@click.option("--clips", default=533, show_default=True, help="Dialogues in the split (DualTalk test: 533).")
@click.option("--reference-clips", default=20, show_default=True, help="Dialogues the reference oscillator runs on.")
@click.option("--seed", default=0, show_default=True, help="Generator seed.")
@click.option("--out", default=RESULTS / "synth", show_default=True, type=click.Path(path_type=Path),
              help="Result to write (.json and .md).")
def main(clips: int, reference_clips: int, seed: int, out: Path) -> None:
    os.environ.setdefault("OMP_NUM_THREADS", "1")
    say = (transcript := Transcript()).say
    say(f"machine: {platform.processor() or platform.machine()}, {os.cpu_count()} cores; load average "
        f"{os.getloadavg()[0]:.1f}")
    memory, *t_memory = timed(lambda: make_clips("test", clips, seed))
    seconds = np.array([c.duration_s for c in memory])
    del memory
    rows = [("in memory (wavetable), 1 process", clips, *t_memory)]
    tmp = Path(tempfile.mkdtemp(prefix="bench-synth-"))
    disk = {}
    try:
        for version, write in WRITERS.items():
            for jobs in (1, 2):
                _, *t = timed(lambda: write(tmp / f"{version}-j{jobs}", split="test", clips=clips, seed=seed,
                                            jobs=jobs, progress=False))
                disk[version, jobs] = t
                rows.append((f"{version} written to disk, --jobs {jobs}", clips, *t))
        size = sum(p.stat().st_size for p in (tmp / "v1-j1" / "test").iterdir())
    finally:
        shutil.rmtree(tmp, ignore_errors=True)
    fast, t_fast, c_fast = timed(lambda: make_clips("test", reference_clips, seed))
    with mock.patch.object(speech, "_synthesise", additive_synthesise):
        slow, t_slow, c_slow = timed(lambda: make_clips("test", reference_clips, seed))
    diff = max(float(np.abs(p.audio - q.audio).max()) for a, b in zip(fast, slow)
               for p, q in zip(a.participants, b.participants))
    same_motion = all(np.array_equal(p.motion, q.motion) for a, b in zip(fast, slow)
                      for p, q in zip(a.participants, b.participants))
    rows += [(f"in memory, wavetable (first {reference_clips})", reference_clips, t_fast, c_fast),
             (f"in memory, additive sines (first {reference_clips}, reference)", reference_clips, t_slow, c_slow)]

    say(f"\nsplit: {clips} dialogues, mean {seconds.mean():.1f} s (min {seconds.min():.1f}, max "
        f"{seconds.max():.1f}), {seconds.sum() / 3600:.2f} h; on disk {size / 1e9:.2f} GB")
    say(f"{'what':<58} {'clips':>6} {'wall s':>8} {'CPU s':>8} {'clips/s':>8}")
    for name, n, wall, cpu in rows:
        say(f"{name:<58} {n:>6} {wall:>8.2f} {cpu:>8.2f} {n / wall:>8.1f}")
    say(f"\nwavetable vs additive sines: {c_slow / c_fast:.1f}x less CPU time; max abs audio difference "
        f"{diff:.2e} (full scale 1); motion identical: {same_motion}")
    ratio = disk["v2", 1][1] / disk["v1", 1][1]
    say(f"v2 / v1 on disk, --jobs 1: {ratio:.2f}x the CPU seconds ({disk['v2', 1][0] / disk['v1', 1][0]:.2f}x "
        f"wall); goal at most {V2_GOAL}x -> {'met' if ratio <= V2_GOAL else 'not met'}")
    best = min(disk["v1", 1][0], disk["v1", 2][0])
    say(f"goal: DualTalk-sized v1 test split on disk in < 60 s wall -> {best:.1f} s "
        f"({'met' if best < 60 and clips >= 533 else 'not met' if clips >= 533 else 'run with --clips 533'}); "
          f"CPU s are what an idle machine would need with --jobs 1 (a busy machine stretches wall time)")
    text = preformatted("Generating a DualTalk-sized synthetic test split", transcript.text())
    print("wrote", *write_result(out, text, seed=seed))


if __name__ == "__main__":
    main()
