"""docs/simulator-python.md's examples run as they stand."""
import re
from pathlib import Path

DOC = Path(__file__).resolve().parents[3] / "docs" / "simulator-python.md"


def python_blocks(path: Path) -> list[str]:
    return re.findall(r"```python\n(.*?)```", path.read_text(), re.S)


def test_the_ten_line_example_drives_a_lap(capsys):
    first = python_blocks(DOC)[0]
    assert len([line for line in first.splitlines() if line.strip()]) <= 13
    exec(compile(first, str(DOC), "exec"), {})
    assert capsys.readouterr().out.startswith("lap_completed ")


def test_the_wrapper_and_vector_example_runs():
    namespace: dict = {}
    for block in python_blocks(DOC)[:2]:
        if "while not done" in block:     # the lap: the test above drives it
            block = block.split("obs, info = env.reset")[0] + "env.close()\n"
        exec(compile(block, str(DOC), "exec"), namespace)
    assert namespace["obs"].shape == (4, 66, 200, 3) and len(set(namespace["info"]["s"])) == 4
    namespace["env"].close()
    namespace["envs"].close()
