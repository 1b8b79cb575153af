"""Error helpers: the closest known name."""
import pytest

from matrix.errors import did_you_mean

AUGMENT = ["flip", "oversample_curves", "curve_threshold", "color_jitter", "blur", "affine"]


@pytest.mark.parametrize("given, known, suggested", [
    ("colour", AUGMENT, "color_jitter"),            # begins alike: closer than 'blur', which shares more letters
    ("montrael", ["montreal", "montmelo", "simple_circuit"], "montreal"),
    ("epoch", ["epochs", "finetune_epochs"], "epochs"),
    ("bulr", AUGMENT, "blur"),                      # short or unlike at the start: the closest by letters
    ("zzz", AUGMENT, None),
])
def test_did_you_mean_names_the_closest_known_name(given, known, suggested):
    assert did_you_mean(given, known) == (f" (did you mean {suggested!r}?)" if suggested else "")


def test_the_full_traceback_shows_what_a_one_line_error_was_raised_from():
    """Outside test: `-v` showed pilotlab's frames alone where a user's brain had failed (`raise ... from None`
    keeps the one-line message short, and cut the user's frames from the traceback too)."""
    from matrix.errors import MatrixError, full_traceback

    def users_code():
        return {}["w"]
    try:
        try:
            users_code()
        except KeyError:
            raise MatrixError("brain.py:2: KeyError: 'w'") from None
    except MatrixError as error:
        text = full_traceback(error)
    assert "in users_code" in text and "KeyError: 'w'" in text
    assert text.rstrip().endswith("MatrixError: brain.py:2: KeyError: 'w'")
