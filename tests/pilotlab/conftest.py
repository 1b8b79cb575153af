import pytest

from tests.pilotlab.tracks import stadium, write_csv


@pytest.fixture
def stadium_csv(tmp_path):
    """A 110 m clockwise stadium (two 30 m straights, 8 m radius bends) as a user circuit CSV."""
    return str(write_csv(tmp_path / "stadium.csv", stadium()))
