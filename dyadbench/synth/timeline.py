"""Who speaks when: floor-holding turns, phrases (inter-pausal units), back-channels and syllables.

Times are in seconds from the clip start. Per participant the result is a :class:`Track`: its phrases
(``kind`` "phrase" inside its own turns, "backchannel" for short listener vocalisations after a partner's
phrase end, "interjection" for short vocalisations overlapping partner speech) and the syllables of those
phrases (onset, duration, amplitude, vowel openness, emphasis). Phrases of one participant never overlap.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from dyadbench.synth.styles import Style, TurnStats

MIN_TURN_LENGTH_S = 1.5


@dataclass(frozen=True)
class Track:
    """One participant's speech plan. Syllable arrays are sorted by onset."""

    phrases: np.ndarray  # (P, 2) start, end (s)
    kinds: tuple[str, ...]  # (P,) "phrase", "backchannel" or "interjection"
    onset: np.ndarray  # (N,) s
    dur: np.ndarray  # (N,) s
    amp: np.ndarray  # (N,) peak envelope
    vowel: np.ndarray  # (N,) 0 = open vowel "a", 1 = spread vowel "i"
    emph: np.ndarray  # (N,) bool: emphasised (pitch accent, louder)
    phrase_of: np.ndarray  # (N,) index into phrases

    def phrase_ends(self, kind: str = "phrase") -> np.ndarray:
        """End times of phrases of ``kind`` (the events listeners respond to)."""
        sel = np.array([k == kind for k in self.kinds], dtype=bool)
        return self.phrases[sel, 1] if len(self.phrases) else np.zeros(0)

    def emphasis_times(self) -> np.ndarray:
        """Peak times of emphasised syllables."""
        return self.onset[self.emph] + self.dur[self.emph] / 2.0


@dataclass(frozen=True)
class Timeline:
    duration_s: float
    turns: tuple[tuple[int, float, float], ...]  # (participant index, start, end)
    tracks: tuple[Track, Track]


def _turns(r: np.random.Generator, duration: float, stats: TurnStats, styles: tuple[Style, Style]
           ) -> list[tuple[int, float, float]]:
    turns: list[tuple[int, float, float]] = []
    last_end = [-1.0, -1.0]
    t = float(r.uniform(0.0, 0.6))
    holder = int(r.integers(2))
    while t < duration - 0.5:
        t = max(t, last_end[holder] + 0.3)
        mean = stats.turn_mean_s * styles[holder].turn_factor
        end = min(t + max(MIN_TURN_LENGTH_S, float(r.gamma(2.0, mean / 2.0))), duration)
        if end - t >= 0.5:
            turns.append((holder, t, end))
            last_end[holder] = end
        gap = float(np.clip(r.normal(stats.gap_mean_s, stats.gap_std_s), -1.5, 2.0))
        t = max(end + gap, t + 1.0)
        holder = 1 - holder
    return turns


def _turn_phrases(r: np.random.Generator, start: float, end: float, stats: TurnStats) -> list[tuple[float, float]]:
    out = []
    s = start
    while s < end - 0.3:
        e = min(s + float(np.clip(r.gamma(3.0, stats.phrase_mean_s / 3.0), 0.4, 5.0)), end)
        out.append((s, e))
        s = e + max(0.15, float(r.gamma(2.0, stats.pause_mean_s / 2.0)))
    return out


def _free(own: list[tuple[float, float, str]], s: float, e: float, margin: float = 0.15) -> bool:
    return all(e + margin <= a or s >= b + margin for a, b, _ in own)


def _listener_vocalisations(r: np.random.Generator, duration: float, stats: TurnStats,
                            styles: tuple[Style, Style], plans: list[list[tuple[float, float, str]]]) -> None:
    """Add back-channels (after partner phrase ends) and interjections (during partner phrases)."""
    partner_phrases = [[(a, b) for a, b, k in plans[1 - p] if k == "phrase"] for p in range(2)]
    for p in range(2):
        tendency = styles[p].backchannel_tendency
        for _, end in partner_phrases[p]:
            if r.random() < min(0.95, stats.backchannel_prob * tendency):
                s = end + float(r.uniform(0.15, 0.45))
                e = s + float(r.uniform(0.25, 0.6))
                if e < duration and _free(plans[p], s, e):
                    plans[p].append((s, e, "backchannel"))
        talk = sum(b - a for a, b in partner_phrases[p])
        for _ in range(int(r.poisson(stats.interjection_rate * tendency * talk))):
            a, b = partner_phrases[p][int(r.integers(len(partner_phrases[p])))]
            s = float(r.uniform(a, max(a, b - 0.3)))
            e = s + float(r.uniform(0.3, 0.8))
            if e < duration and _free(plans[p], s, e):
                plans[p].append((s, e, "interjection"))


def _syllables(r: np.random.Generator, phrases: list[tuple[float, float, str]], style: Style) -> Track:
    onsets, durs, amps, vowels, emphs, owners = [], [], [], [], [], []
    for i, (s, e, kind) in enumerate(phrases):
        rate = style.syllable_rate * (0.6 if kind != "phrase" else 1.0)
        n_max = int(np.ceil((e - s) * rate * 1.4)) + 2
        d = r.uniform(0.8, 1.25, n_max) / rate
        on = s + np.concatenate([[0.0], np.cumsum(d)[:-1]])
        keep = on < e - 0.05
        on, d = on[keep], np.minimum(d[keep], e - on[keep])
        n = len(on)
        quiet = kind != "phrase"
        amp = r.uniform(0.4, 0.7, n) if quiet else r.uniform(0.55, 1.0, n)
        emph = np.zeros(n, dtype=bool) if quiet else r.random(n) < 0.12
        if not quiet and n >= 3 and not emph.any():
            emph[int(r.integers(n))] = True
        amp = np.where(emph, 1.3, amp)
        onsets.append(on), durs.append(d), amps.append(amp), emphs.append(emph)
        vowels.append(r.uniform(0.0, 1.0, n)), owners.append(np.full(n, i))
    cat = (lambda xs, dtype=np.float64: np.concatenate(xs).astype(dtype) if xs else np.zeros(0, dtype))
    return Track(phrases=np.array([(s, e) for s, e, _ in phrases]).reshape(-1, 2),
                 kinds=tuple(k for _, _, k in phrases), onset=cat(onsets), dur=cat(durs), amp=cat(amps),
                 vowel=cat(vowels), emph=cat(emphs, bool), phrase_of=cat(owners, np.int64))


def make_timeline(r: np.random.Generator, duration: float, stats: TurnStats,
                  styles: tuple[Style, Style]) -> Timeline:
    """Plan a conversation of ``duration`` seconds between two people."""
    turns = _turns(r, duration, stats, styles)
    plans: list[list[tuple[float, float, str]]] = [[], []]
    for holder, start, end in turns:
        plans[holder].extend((s, e, "phrase") for s, e in _turn_phrases(r, start, end, stats))
    _listener_vocalisations(r, duration, stats, styles, plans)
    tracks = tuple(_syllables(r, sorted(plans[p]), styles[p]) for p in range(2))
    return Timeline(duration_s=duration, turns=tuple(turns), tracks=tracks)  # type: ignore[arg-type]
