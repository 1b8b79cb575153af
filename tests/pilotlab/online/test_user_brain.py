"""A brain the user wrote (pilotlab.online.brains.UserBrain) drives in the simulator with every metric,
and whatever goes wrong in its code is one line naming the file and line."""
import re
from pathlib import Path

import numpy as np
import pytest

from pilotlab.errors import PilotlabError
from pilotlab.online.brains import UserBrain
from pilotlab.online.evaluate import OnlineSpec, evaluate_online
from pilotlab.usercode import UserCodeError
from tests.pilotlab.user_brains import write_red_line

SPEC = "brains/mine.py:RedLine"


def test_a_red_line_controller_drives_a_stretch_of_simple_circuit(tmp_path):
    write_red_line(tmp_path)
    brain = UserBrain(SPEC, tmp_path, name="mine")
    spec = OnlineSpec(circuit="simple_circuit", timeout_s=10.0, timing="measured")   # its own time, on this host
    result = evaluate_online(brain, spec, tmp_path / "lap")
    assert result["brain"] == "mine" and result["runs"][0]["termination"] == "timeout"
    assert result["completed_distance_m"] > 50 and result["position_deviation_mae_m"] < 1.0
    assert result["off_road_events"] == 0 and result["mean_inference_ms"] > 0
    assert (tmp_path / "lap" / "trajectory.png").is_file() and brain.brain.resets == 2   # its own, then one per run


def test_options_go_to_the_constructor(tmp_path):
    write_red_line(tmp_path)
    brain = UserBrain(SPEC, tmp_path, options={"speed": 4.0})
    assert brain.name == "RedLine" and brain.brain.speed == 4.0
    image = np.zeros((480, 640, 3), np.uint8)
    image[400:, 330:340] = (205, 30, 30)     # the line a little right of the centre
    v, w = brain.act(image, {})
    assert v == 4.0 and w < 0 and brain.last_inference_s > 0


BROKEN = {
    "act raises": ("class B:\n    def act(self, image):\n        return 1 / 0\n",
                   ":3: ZeroDivisionError: division by zero (in brains/bad.py:B.act)"),
    "act returns one number": ("class B:\n    def act(self, image):\n        return 5.0\n",
                               "bad.py:3: act returned 5.0; it must return (v, w)"),
    "act returns text": ("class B:\n    def act(self, image):\n        return '5', '0'\n",
                         "bad.py:3: act returned ('5', '0'); it must return (v, w), two finite numbers (m/s and rad/s) "
                         "(in brains/bad.py:B.act)"),
    # outside test: a wrong value was said at act's def line; its return statement is the line to look at
    "act returns None on a branch": ("class B:\n    def act(self, image):\n        if image is None:\n"
                                     "            return 1.0, 0.0\n        v = 2.0\n        return v\n",
                                     "brains/bad.py:2 (returns at lines 4, 6): act returned 2.0"),
    "act without return": ("class B:\n    def act(self, image):\n        def inner():\n            return 1.0, 0.0\n"
                           "        inner()\n",
                           "brains/bad.py:2 (no return statement: it returns None): act returned None"),
    "no act": ("class B:\n    def drive(self, image):\n        return 5.0, 0.0\n", "brains/bad.py:B: has no act(image)"),
    "constructor raises": ("class B:\n    def __init__(self):\n        raise ValueError('no weights')\n",
                           ":3: ValueError: no weights (making brains/bad.py:B)"),
}


def test_a_network_s_output_row_is_a_command(tmp_path):
    (tmp_path / "brains").mkdir()
    (tmp_path / "brains" / "net.py").write_text("import numpy as np\nclass B:\n    def act(self, image):\n"
                                                "        return np.array([[5.0, 0.25]], np.float32)\n")
    assert UserBrain("brains/net.py:B", tmp_path).act(np.zeros((48, 64, 3), np.uint8), {}) == (5.0, 0.25)


@pytest.mark.parametrize("case", BROKEN)
def test_a_broken_brain_is_one_line_naming_file_and_line(tmp_path, case):
    source, expected = BROKEN[case]
    (tmp_path / "brains").mkdir()
    (tmp_path / "brains" / "bad.py").write_text(source)
    with pytest.raises(PilotlabError) as caught:
        brain = UserBrain("brains/bad.py:B", tmp_path)
        brain.act(np.zeros((48, 64, 3), np.uint8), {})
    message = str(caught.value)
    assert expected in message and "\n" not in message
    if expected.startswith(":"):
        assert message.startswith(str(tmp_path / "brains" / "bad.py") + expected.split(" ")[0])


def test_a_syntax_error_names_its_line(tmp_path):
    (tmp_path / "brains").mkdir()
    (tmp_path / "brains" / "bad.py").write_text("class B:\n    def act(self, image)\n        return 5.0, 0.0\n")
    with pytest.raises(UserCodeError, match=r"bad\.py:2: syntax error"):
        UserBrain("brains/bad.py:B", tmp_path)


def test_the_brain_in_the_docs_loads_and_steers_towards_the_line(tmp_path):
    doc = Path(__file__).resolve().parents[3] / "docs" / "brains.md"
    source = re.findall(r"```python\n(.*?)```", doc.read_text(), re.S)[0]
    (tmp_path / "brains").mkdir()
    (tmp_path / "brains" / "mine.py").write_text(source)
    brain = UserBrain("brains/mine.py:MyBrain", tmp_path)
    image = np.zeros((480, 640, 3), np.uint8)
    image[240:, 100:110] = (205, 30, 30)       # the line on the left
    v, w = brain.act(image, {})
    assert v == 7.0 and w > 0
