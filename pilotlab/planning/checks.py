"""Recipe checks the planner makes on what a recipe names (beside pilotlab.definitions' checks of its
definitions): each a recipe error at the key to change, before any job runs."""
from __future__ import annotations

from pathlib import Path

from matrix.recipe import Recipe
from pilotlab.recipe import DatasetSpec


def check_bag_topics(recipe: Recipe, name: str, spec: DatasetSpec, value: str, source: Path, i: int) -> None:
    """The dataset's topics are in this bag (its index only; pilotlab.data.bag_topics), else a recipe error
    naming every one it lacks, at the key to change."""
    from pilotlab.data.bag_topics import bag_topics, listing, missing_topics
    from pilotlab.data.folder_rows import is_dataset_folder
    topics = None if is_dataset_folder(source) else bag_topics(source)
    missing = [] if topics is None else missing_topics(topics, spec.topics.image, spec.topics.command)
    if not missing:
        return
    lacks = " and ".join(phrase for _, phrase in missing)
    given = [role for role, _ in missing if getattr(spec.topics, role) is not None]
    where = ["datasets", name] + (["topics", given[0]] if len(given) == 1 else ["topics"] if given else ["bags", i])
    raise recipe.error(f"bag {value}: {lacks}; topics present: {listing(topics)}; name the bag's topics in the "
                       "dataset (topics: {image: NAME, command: NAME}), or give a bag with other topic names a "
                       "dataset of its own", where)


def check_test_set(recipe: Recipe, config) -> None:
    """The default test set ("test") missing from a recipe that never named one: say what it is for."""
    name = config.offline.data
    if name not in config.datasets and "data" not in config.offline.model_fields_set:
        raise recipe.error(
            f"the offline evaluation (MSE, size, timing) needs a test set, and dataset {name!r} is not defined "
            f"(datasets: {', '.join(config.datasets) or 'none'}); add one, e.g. `{name}: {{record: {{circuits: "
            "[simple_circuit], laps: 0.5, seed: 2}}`, or measure on another dataset with `offline: {data: NAME}`",
            ["datasets"])
