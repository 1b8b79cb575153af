"""Planning mutated recipes the way `pilotlab plan` does, counting how each one ended."""
from __future__ import annotations

import random
import shutil
import signal
import time
import traceback
from collections import Counter
from dataclasses import dataclass, field
from pathlib import Path

from matrix import engine
from matrix.errors import MatrixError
from matrix.recipe import load_recipe
from matrix.store import Store
from pilotlab.domain import DOMAIN
from tests.pilotlab.fuzz.recipes import base_texts, mutate
from tests.pilotlab.tracks import stadium, write_csv

HANG_S = 10


class Hang(Exception):
    pass


@dataclass
class Outcomes:
    counts: Counter = field(default_factory=Counter)
    tracebacks: list[str] = field(default_factory=list)
    slowest_s: float = 0.0

    def summary(self) -> str:
        return f"{dict(self.counts)}, slowest {self.slowest_s:.2f} s"


def recipe_folder(folder: Path) -> Path:
    """The files the small recipes name: a DLS folder, a bag file, a circuit CSV (only hashed by plan)."""
    (folder / "dls").mkdir(parents=True, exist_ok=True)
    (folder / "dls" / "data.csv").write_text("image_name,v,w\n0.png,1,0\n")
    (folder / "run.bag").write_bytes(b"#ROSBAG V2.0\n" + bytes(100))
    write_csv(folder / "track.csv", stadium())
    return folder


def _alarm(signum, frame):
    raise Hang(f"planning took longer than {HANG_S} s")


def plan_one(path: Path, store: Store, outcomes: Outcomes) -> None:
    started = time.monotonic()
    previous = signal.signal(signal.SIGALRM, _alarm)
    signal.alarm(HANG_S)
    try:
        engine.make_plan(load_recipe(path, DOMAIN), DOMAIN, store)
        outcomes.counts["planned"] += 1
    except MatrixError as error:
        message = str(error)
        outcomes.counts["refused" if "\n" not in message and len(message) < 1000 else "long message"] += 1
        if "\n" in message or len(message) >= 1000:
            outcomes.tracebacks.append(f"{path.read_bytes()[:3000]!r}\nMESSAGE {message[:3000]!r}")
    except Hang:
        outcomes.counts["hang"] += 1
        outcomes.tracebacks.append(f"{path.read_bytes()[:3000]!r}\nHANG")
    except Exception:   # noqa: BLE001 - what the test counts
        outcomes.counts["traceback"] += 1
        outcomes.tracebacks.append(f"{path.read_bytes()[:3000]!r}\n{traceback.format_exc()}")
    finally:
        signal.alarm(0)
        signal.signal(signal.SIGALRM, previous)
        outcomes.slowest_s = max(outcomes.slowest_s, time.monotonic() - started)


def fuzz(folder: Path, count: int, seed: int = 0, bases: list[tuple[str, str]] | None = None) -> Outcomes:
    rng, outcomes = random.Random(seed), Outcomes()
    bases = bases or base_texts()
    recipe_folder(folder)
    store = Store(folder / "store")
    for i in range(count):
        name, text = bases[i % len(bases)]
        path = folder / name
        path.write_bytes(mutate(text, rng).encode("utf-8", "surrogatepass"))
        plan_one(path, store, outcomes)
    shutil.rmtree(folder / "store", ignore_errors=True)
    return outcomes


def write_mutations(folder: Path, count: int, seed: int) -> list[Path]:
    """`count` mutated recipes as files (for the command line)."""
    rng, bases, paths = random.Random(seed), base_texts(), []
    recipe_folder(folder)
    for i in range(count):
        name, text = bases[i % len(bases)]
        path = folder / f"{i}_{name}"
        path.write_bytes(mutate(text, rng).encode("utf-8", "surrogatepass"))
        paths.append(path)
    return paths
