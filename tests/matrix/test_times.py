"""How long a job is expected to take (matrix.times.KindStats): what it took here, what its kind says of
its params, what its kind took here, what its kind says it typically takes."""
import pytest

from matrix.errors import MatrixError
from matrix.kinds import KINDS, register_kind
from matrix.store import Store
from matrix.times import DEFAULT_ESTIMATE_S, KindStats


@pytest.fixture
def kinds():
    register_kind("flat_toy", lambda ctx: {}, typical_s=4.0)
    register_kind("laps_toy", lambda ctx: {}, typical_for=lambda params: 6.0 * params.get("laps", 1))
    register_kind("odd_toy", lambda ctx: {}, typical_for=lambda params: 1 / 0)
    yield
    for name in ("flat_toy", "laps_toy", "odd_toy"):
        KINDS._entries.pop(name)


def test_a_job_s_own_time_then_its_kind_s_guess_for_its_params_then_the_kind_s_mean(tmp_path, kinds):
    stats = KindStats(Store(tmp_path))
    assert stats.estimate("flat_toy", "a") == 4.0 and stats.estimate("laps_toy", "b", {"laps": 3}) == 18.0
    stats.add("flat_toy", 9.0, "a")
    stats.add("laps_toy", 7.0, "b")
    assert stats.estimate("flat_toy", "a") == 9.0 and stats.estimate("laps_toy", "b", {"laps": 3}) == 7.0
    # the kind's mean here beats its flat guess (same work, this machine); a guess by params beats the
    # mean of jobs with other params (a tolerance search is a dozen laps)
    assert stats.estimate("flat_toy", "c") == 9.0
    assert stats.estimate("laps_toy", "d", {"laps": 12}) == 72.0


def test_a_guess_that_fails_is_no_guess_and_an_unknown_kind_gets_the_median(tmp_path, kinds):
    stats = KindStats(Store(tmp_path))
    assert stats.estimate("odd_toy", "x", {}) == DEFAULT_ESTIMATE_S
    for kind, seconds in (("k1", 1.0), ("k2", 2.0), ("k3", 30.0)):
        stats.add(kind, seconds)
    assert stats.estimate("odd_toy", "x", {}) == 2.0 == stats.estimate("never_registered")


@pytest.mark.parametrize("seconds", [0, -1.0, float("inf"), float("nan")])
def test_a_typical_time_is_a_positive_number(seconds):
    with pytest.raises(MatrixError, match="typical_s must be a positive number"):
        register_kind("bad_toy", lambda ctx: {}, typical_s=seconds)
    assert "bad_toy" not in KINDS


def test_a_guess_by_params_is_scaled_by_how_far_off_the_kind_s_guesses_were_here(tmp_path, kinds):
    """The study's first laps of Montreal and fine-tunes on its larger data took 3-4 times the guesses
    made on the development machine's quickstart: what the kind's jobs took here corrects its guesses,
    and a guess by params still tells a tolerance search from a plain lap."""
    stats = KindStats(Store(tmp_path))
    assert not stats.measured("laps_toy")
    stats.add("laps_toy", 12.0, "b", {"laps": 1})      # guessed 6 s: twice as long here
    assert stats.measured("laps_toy") and stats.estimate("laps_toy", "d", {"laps": 12}) == 144.0
    stats.save()
    assert KindStats(Store(tmp_path)).estimate("laps_toy", "d", {"laps": 12}) == 144.0
    stats.add("flat_toy", 9.0, "a", {})                # a flat guess: the kind's mean does the scaling
    assert stats.measured("flat_toy") and stats.estimate("flat_toy", "c") == 9.0
    stats.add("odd_toy", 9.0, "o", {})                 # a guess that fails: nothing to compare with
    assert not stats.measured("odd_toy")


@pytest.mark.parametrize("seconds", ["30", True, None])
def test_a_typical_time_of_another_type_is_refused_with_the_kind_s_name(seconds):
    if seconds is None:   # None means "no guess"
        register_kind("none_toy", lambda ctx: {}, typical_s=seconds)
        assert KINDS.get("none_toy").typical({}) is None
        KINDS._entries.pop("none_toy")
        return
    with pytest.raises(MatrixError, match="'bad_toy': typical_s must be a positive number"):
        register_kind("bad_toy", lambda ctx: {}, typical_s=seconds)


def test_a_guess_by_params_may_say_it_has_none(tmp_path):
    register_kind("shy_toy", lambda ctx: {}, typical_for=lambda params: None)
    try:
        assert KINDS.get("shy_toy").typical({}) is None
        assert KindStats(Store(tmp_path)).estimate("shy_toy", "x", {}) == DEFAULT_ESTIMATE_S
    finally:
        KINDS._entries.pop("shy_toy")


def test_a_guess_given_apart_from_the_registration_replaces_the_kind_s(kinds):
    """guess_kind: a domain writes its guesses in a module that is no kind's code (tuning one re-keys no job)."""
    from matrix.kinds import guess_kind
    from matrix.registry import UnknownNameError
    before = KINDS.get("flat_toy")
    guess_kind("flat_toy", typical_for=lambda params: 2.0 * params["laps"])
    assert KINDS.get("flat_toy").typical({"laps": 3}) == 6.0 and KINDS.get("flat_toy").target is before.target
    guess_kind("flat_toy", typical_s=5.0)
    assert KINDS.get("flat_toy").typical({"laps": 3}) == 5.0
    with pytest.raises(MatrixError, match="'flat_toy': typical_s must be a positive number"):
        guess_kind("flat_toy", typical_s=-1.0)
    with pytest.raises(UnknownNameError, match="flat_toy"):   # the known ones are named
        guess_kind("flat_tyo", typical_s=1.0)
