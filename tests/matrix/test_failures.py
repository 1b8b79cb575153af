"""How a failed job's error is stored: the domain's own errors as their message, bugs with their type."""
from matrix.errors import MatrixError, RecipeError
from matrix.worker import failure_message


class DomainError(MatrixError):
    pass


def test_an_error_raised_on_purpose_is_stored_as_its_message():
    assert failure_message(DomainError("run.bag, topic /cmd: 3 of 60 messages are lost; record it again")) == \
        "run.bag, topic /cmd: 3 of 60 messages are lost; record it again"
    assert failure_message(RecipeError("bad", file="r.yaml", line=3)) == "r.yaml:3: bad"


def test_anything_else_is_a_bug_named_by_its_type_on_one_line():
    assert failure_message(OverflowError("cannot convert float infinity to integer\nmore")) == \
        "OverflowError: cannot convert float infinity to integer"
    assert failure_message(KeyError()) == "KeyError"
    cut = failure_message(ValueError("x" * 1000))
    assert len(cut) == 300 and cut.endswith("…")


def test_a_long_message_raised_on_purpose_keeps_its_fix_at_the_end():
    """Outside test: cut at 300 characters, a bag's topic listing left out "set the topic ..." and a fixed
    batch ONNX file's message its dynamic_axes advice, in the run's line, `show` and the report."""
    topics = ", ".join(f"/robot/sensor_{i} (sensor_msgs/msg/Image, 120 messages)" for i in range(12))
    message = f"run.bag: the bag has no topic '/cmd_vel'; topics present: {topics}; set the command topic to one of them"
    assert failure_message(DomainError(message)) == message
    cut = failure_message(DomainError("y" * 5000))
    assert len(cut) == 2000 and cut.endswith("…")


def test_a_nan_anywhere_in_a_result_is_found():
    from matrix.worker import non_finite
    assert non_finite({"mse": 0.1, "history": [{"loss": 1.0}, {"loss": float("nan")}]}) == "history.1.loss = nan"
    assert non_finite({"latency_ms": float("inf")}) == "latency_ms = inf"
    assert non_finite({"mse": 0.1, "name": "x", "n": 3, "none": None}) is None
