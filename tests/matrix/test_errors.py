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
