"""Seeded mutations of recipes: the committed ones and small valid ones, changed the ways people and
files get them wrong (a value of the wrong type, a huge or hostile value, a path that is not data, a
key dropped or renamed, text cut, lines swapped, a control character typed in)."""
from __future__ import annotations

import copy
import random
from pathlib import Path
from typing import Any

import yaml

ROOT = Path(__file__).resolve().parents[3]
COMMITTED = sorted((ROOT / "recipes").glob("*.yaml"))

SMALL = [
    """\
name: fuzz_small
datasets:
  train: {record: {circuits: [simple_circuit], directions: [cw, ccw], laps: 0.2}}
  test: {record: {circuits: [simple_circuit], laps: 0.1, seed: 3}}
models:
  small: {epochs: 1, batch_size: 8}
strategies:
  local_prune: {conv: 0.3, finetune_epochs: 1}
  prune_more: {use: local_prune, conv: 0.5}
hardware:
  cpu2: {device: cpu, threads: 2}
online: {timing: latency, directions: [cw], repetitions: 1}
matrix:
  model: [small]
  strategy: [baseline, local_prune, prune_more]
  hardware: [cpu, cpu2]
  circuit: [simple_circuit]
""",
    """\
name: fuzz_data
datasets:
  train: {folders: [dls], topics: {image: /cam, command: /cmd}}
  test: {bags: [run.bag]}
circuits:
  track: {csv: track.csv}
models:
  m: {arch: pilotnet, epochs: 1, labels: {v: [0, 5], w: [-1, 1]}}
offline: {data: test, batch: 8}
matrix:
  model: [m]
  strategy: [baseline, dynamic_quant]
  circuit: [track]
  include: [{model: m, strategy: half, hardware: cuda}]
  exclude: [{strategy: dynamic_quant, circuit: track}]
""",
]

# Values a mutation puts in place of a node: wrong types, edge numbers, hostile strings and paths.
VALUES: list[Any] = [
    None, True, False, 0, -1, 1, 2**64 + 1, -(2**63), 1e308, -1e308, 1e-320, float("nan"), float("inf"),
    0.5, "", " ", "x", "a" * 5000, "../" * 30 + "etc/passwd", "/proc/self/mem", "/", "/dev/zero",
    "~nosuchuser/x.bag", "dls", "run.bag", "track.csv", "baseline", "cuda", "cpu", "pilotnet", "simple_circuit",
    "montreal", "local_prune", "train", "test", "use", "{{ x }}", "$(touch /tmp/pwned)", "\u202e", "ä",
    [], {}, [None], ["a", "b"], [[1, 2]], {"use": ["a", "b"]}, {"use": {}}, {"a": {"b": {"c": {}}}},
    {"record": {"circuits": []}}, {"csv": "/"}, [{"model": "x"}], list(range(30)),
]
KEYS = ["name", "datasets", "models", "strategies", "hardware", "circuits", "offline", "online", "report",
        "matrix", "include", "exclude", "use", "record", "bags", "folders", "laps", "epochs", "arch",
        "options", "device", "threads", "csv", "batch", "data", "topics", "labels", "augment", "x"]


def base_texts() -> list[tuple[str, str]]:
    return [(path.name, path.read_text()) for path in COMMITTED] + [(f"small{i}.yaml", t) for i, t in enumerate(SMALL)]


def mutate(text: str, rng: random.Random) -> str:
    """One to three mutations of a recipe's text, structural (on the parsed document) or textual."""
    for _ in range(rng.randint(1, 3)):
        text = (_structural if rng.random() < 0.7 else _textual)(text, rng)
    return text


def _structural(text: str, rng: random.Random) -> str:
    try:
        document = yaml.safe_load(text)
    except yaml.YAMLError:
        return _textual(text, rng)
    if not isinstance(document, dict):
        return _textual(text, rng)
    document = copy.deepcopy(document)
    paths = list(_paths(document, ()))
    path = rng.choice(paths)
    parent, key = _parent(document, path)
    operation = rng.random()
    if operation < 0.55:
        parent[key] = copy.deepcopy(rng.choice(VALUES))
    elif operation < 0.7 and isinstance(parent, dict):
        del parent[key]
    elif operation < 0.8 and isinstance(parent, dict):
        parent[rng.choice(KEYS)] = parent.pop(key)
    elif operation < 0.9 and isinstance(parent[key], (list, dict)):
        parent[key] = [parent[key]] * rng.randint(2, 4) if isinstance(parent[key], list) else {**parent[key], rng.choice(KEYS): rng.choice(VALUES)}
    else:
        parent[key] = copy.deepcopy(parent[rng.choice(list(parent) if isinstance(parent, dict) else range(len(parent)))])
    return yaml.safe_dump(document, allow_unicode=True, sort_keys=False)


def _paths(node: Any, path: tuple):
    if path:
        yield path
    items = node.items() if isinstance(node, dict) else enumerate(node) if isinstance(node, list) else ()
    for key, child in items:
        yield from _paths(child, path + (key,))


def _parent(document: Any, path: tuple) -> tuple[Any, Any]:
    node = document
    for key in path[:-1]:
        node = node[key]
    return node, path[-1]


def _textual(text: str, rng: random.Random) -> str:
    lines = text.splitlines(keepends=True)
    operation = rng.random()
    if operation < 0.2 and text:
        cut = rng.randrange(len(text))
        return text[:cut]
    if operation < 0.4 and len(lines) > 1:
        i, j = rng.randrange(len(lines)), rng.randrange(len(lines))
        lines[i], lines[j] = lines[j], lines[i]
        return "".join(lines)
    if operation < 0.55 and lines:
        i = rng.randrange(len(lines))
        return "".join(lines[:i] + [lines[i]] * 2 + lines[i + 1:])
    position = rng.randrange(len(text) + 1)
    insert = rng.choice(["\x07", "\x00", "\t", "{", "[", "]", "}", ":", "'", '"', "&a ", "*a", "!!python/object ",
                         "<<: ", "- ", "#", "\ufeff", "\ud800", "  ", "\n", "%YAML 1.1\n", "---\n", "? "])
    return text[:position] + insert + text[position:]
