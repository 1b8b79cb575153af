"""Validation splits never put random frames of one run on both sides."""
import numpy as np
import pytest
from hypothesis import given, strategies as st

from pilotlab.data.split import split_validation
from pilotlab.errors import PilotlabError


@given(st.lists(st.integers(1, 40), min_size=2, max_size=6), st.floats(0.05, 0.9), st.integers(0, 99))
def test_by_recording_holds_out_whole_recordings(sizes, fraction, seed):
    recording = np.repeat(np.arange(len(sizes)), sizes)
    split = split_validation(recording, fraction, "recording", seed)
    train_runs, val_runs = set(recording[split.train]), set(recording[split.val])
    assert train_runs and val_runs and not train_runs & val_runs
    assert sorted(val_runs) == split.val_recordings and split.by == "recording"
    assert len(split.train) + len(split.val) == len(recording)


def test_by_recording_aims_at_the_fraction():
    recording = np.repeat(np.arange(10), 100)
    split = split_validation(recording, 0.3, "recording", seed=0)
    assert len(split.val) == 300 and len(split.val_recordings) == 3


def test_by_block_holds_out_the_end_of_every_recording():
    recording = np.repeat([0, 1], [10, 20])
    split = split_validation(recording, 0.2, "block")
    assert list(split.val) == [8, 9, 26, 27, 28, 29] and split.by == "block"


def test_one_recording_is_split_by_block():
    split = split_validation(np.zeros(10, np.int32), 0.3)
    assert split.by == "block" and list(split.val) == [7, 8, 9]


def test_no_validation():
    split = split_validation(np.zeros(5), 0.0)
    assert len(split.val) == 0 and len(split.train) == 5


def test_bad_split_settings():
    with pytest.raises(PilotlabError, match="validation split .random. is not one of auto, recording, block"):
        split_validation(np.zeros(5), 0.2, "random")
    with pytest.raises(PilotlabError, match="val_fraction = 1.0 must be at least 0 and below 1"):
        split_validation(np.zeros(5), 1.0)


def test_auto_holds_out_recordings_only_when_two_stay_in_training():
    assert split_validation(np.repeat([0, 1], 10), 0.2).by == "block"
    assert split_validation(np.repeat([0, 1, 2], 10), 0.2).by == "recording"
