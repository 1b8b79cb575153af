"""`pilotlab record`, through the real command line: the closing line says how the drive ended in words."""
import pytest

from pilotlab.cli import main
from pilotlab.sim.env import describe_end


def test_a_short_recording_says_it_drove_the_fraction_asked_for(tmp_path, capsys):
    assert main(["record", "--circuit", "simple_circuit", "--laps", "0.05", "--size", "64x48",
                 "--out", str(tmp_path / "short.bag")]) == 0
    out = capsys.readouterr().out
    assert "(drove the 0.05 lap asked for)" in out and "lap_completed" not in out


@pytest.mark.parametrize("termination, laps, words", [
    ("lap_completed", 1, "1 lap completed"), ("lap_completed", 2, "2 laps completed"),
    ("lap_completed", 0.1, "drove the 0.1 lap asked for"), ("off_road", 1, "left the road"),
    ("timeout", 1, "timed out"), (None, 1, "stopped")])
def test_every_ending_has_words(termination, laps, words):
    assert describe_end(termination, laps) == words
