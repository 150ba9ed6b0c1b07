"""The v1 realism and causal-structure checks, run on v2 clips: the checks are imported from
tests/test_synth_structure.py and tests/test_synth_corpus.py (pytest collects them here) and read this
module's fixtures, which generate the same splits, seeds and clip counts with the v2 generator."""

import pytest

from dyadbench.synth.corpus_v2 import make_clips
from tests.test_synth_corpus import (  # noqa: F401  (collected here, on v2 clips)
    test_audio_is_speech_while_speaking_and_near_silence_otherwise, test_ood_differs_measurably_from_train,
    test_statistics_within_calibration_ranges, test_talk_and_overlap_fractions_within_calibration)
from tests.test_synth_structure import (  # noqa: F401  (collected here, on v2 clips)
    test_expressions_mirror_the_partner_with_a_lag, test_jaw_does_not_follow_partner_speech,
    test_jaw_follows_own_speech_envelope_with_a_small_lag, test_listener_nods_after_partner_speech_offsets,
    test_listener_smiles_after_partner_speech_offsets)


@pytest.fixture(scope="module")
def clips():
    return make_clips("train", 10, seed=5)


@pytest.fixture(scope="module")
def train_clips():
    return make_clips("train", 8, seed=0)


@pytest.fixture(scope="module")
def ood_clips():
    return make_clips("ood", 8, seed=0)
