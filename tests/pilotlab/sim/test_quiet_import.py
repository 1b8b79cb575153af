"""Loading the simulator prints nothing: pybullet's "pybullet build time: …" line is swallowed."""
import subprocess
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[3]


def test_loading_the_simulator_prints_no_pybullet_build_time():
    run = subprocess.run([sys.executable, "-c", "import pilotlab.sim.world, pilotlab.sim.car, pilotlab.sim.render; "
                          "import sys; print('ok', file=sys.stderr)"],
                         cwd=ROOT, capture_output=True, text=True, timeout=120)
    assert run.returncode == 0 and run.stderr == "ok\n" and run.stdout == ""
