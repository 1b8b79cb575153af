"""A small pilotlab recipe run with one job at a time and with several: the same jobs, the same
results (measurements apart) and the same recorded and trained files."""
import hashlib

import pytest

from matrix import engine
from matrix.store import Store
from pilotlab.domain import DOMAIN
from tests.pilotlab.test_dask_pipeline import assert_same_results, results


def file_hashes(store: Store, kinds=("record", "frames", "train", "optimize")) -> dict[str, str]:
    """sha256 of the data files (bags, frame arrays, models) of the jobs of `kinds`, by job name and
    file. JSON files are left out (they note how long things took); a checkpoint counts by its weights
    (it embeds its training history, seconds included)."""
    import torch
    hashes = {}
    for key in store.keys():
        spec = store.spec(key)
        if spec["kind"] not in kinds:
            continue
        for path in sorted(p for p in store.artifacts(key).rglob("*") if p.is_file() and p.suffix != ".json"):
            name = f"{spec['name']}/{path.relative_to(store.artifacts(key))}"
            if path.suffix == ".pt":
                weights = torch.load(path, weights_only=False, map_location="cpu")["state_dict"]
                content = b"".join(tensor.numpy().tobytes() for tensor in weights.values())
            else:
                content = path.read_bytes()
            hashes[name] = hashlib.sha256(content).hexdigest()
    return hashes


@pytest.mark.slow
def test_several_jobs_at_once_give_the_results_of_one_at_a_time(tmp_path, pipeline_one_at_a_time):
    recipe, one, one_plan = pipeline_one_at_a_time
    many = Store(tmp_path / "many")
    many_plan = engine.make_plan(recipe, DOMAIN, many)
    assert not engine.run_plan(many_plan, DOMAIN, many, jobs=3).failed
    assert sorted(one.keys()) == sorted(many.keys())
    assert_same_results(results(one, one_plan), results(many, many_plan))
    hashes = file_hashes(one)
    assert any(name.endswith("model.pt") for name in hashes) and any(name.startswith("record ") for name in hashes)
    assert file_hashes(many) == hashes
