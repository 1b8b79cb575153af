"""The artifact a strategy writes: one model file in a deployable format plus `artifact.json`.

    artifact.json = {
      "artifact_format": "pilotlab-artifact/1",
      "strategy": "onnxruntime_int8", "strategy_version": 1,
      "format": "onnx",                 # "onnx" | "torchscript" | "pilotlab-checkpoint"
      "file": "model.onnx",
      "runtime": "onnxruntime",         # "onnxruntime" | "torch"
      "device": "cpu",                  # where it is meant to run ("cpu" | "cuda")
      "dtype": "int8",                  # the precision of the weights/compute
      "input": {"name": "images", "shape": [null, 3, 66, 200], "dtype": "float32",
                "layout": "NCHW, RGB in [0, 1]"},
      "output": {"name": "vw", "shape": [null, 2], "meaning": "normalised (v, w)"},
      "arch": "pilotnet", "config": {...},            # from the trained checkpoint
      "labels": {"v": [lo, hi], "w": [lo, hi]}, "preprocess": {...},
      "extra": {...}                                  # strategy specifics (sparsity, quantizer...)
    }

The input is always float32 (the predictor casts for half-precision artifacts), so every consumer
feeds the same tensor whatever the strategy.
"""
from __future__ import annotations

import json
import zlib
from dataclasses import asdict, dataclass, field
from pathlib import Path
from typing import Any

from pilotlab.errors import PilotlabError

ARTIFACT_FORMAT = "pilotlab-artifact/1"
META_FILE = "artifact.json"
INPUT_NAME, OUTPUT_NAME = "images", "vw"
FLOAT_FORMATS = ("checkpoint", "torchscript", "onnx")   # how a float model (pruned, clustered) is saved


@dataclass(frozen=True)
class ArtifactMeta:
    strategy: str
    strategy_version: int
    format: str
    file: str
    runtime: str
    dtype: str
    input_shape: tuple               # (None, C, H, W): None = any batch size
    arch: str
    config: dict[str, Any]
    labels: dict[str, Any]
    preprocess: dict[str, Any] = field(default_factory=dict)
    device: str = "cpu"
    extra: dict[str, Any] = field(default_factory=dict)

    def to_json(self) -> dict[str, Any]:
        data = asdict(self)
        shape = list(data.pop("input_shape"))
        return {"artifact_format": ARTIFACT_FORMAT, **{k: data[k] for k in (
            "strategy", "strategy_version", "format", "file", "runtime", "device", "dtype")},
            "input": {"name": INPUT_NAME, "shape": shape, "dtype": "float32",
                      "layout": "NCHW, RGB in [0, 1]"},
            "output": {"name": OUTPUT_NAME, "shape": [None, 2], "meaning": "normalised (v, w)"},
            **{k: data[k] for k in ("arch", "config", "labels", "preprocess", "extra")}}

    @classmethod
    def from_json(cls, data: dict[str, Any]) -> ArtifactMeta:
        fields = {k: data[k] for k in ("strategy", "strategy_version", "format", "file", "runtime",
                                       "dtype", "arch", "config", "labels", "preprocess", "device", "extra")}
        return cls(input_shape=tuple(data["input"]["shape"]), **fields)


def write_meta(out: Path, meta: ArtifactMeta) -> None:
    tmp = Path(out) / (META_FILE + ".tmp")
    tmp.write_text(json.dumps(meta.to_json(), indent=1))
    tmp.replace(Path(out) / META_FILE)


def read_meta(artifact_dir: Path) -> ArtifactMeta:
    path = Path(artifact_dir) / META_FILE
    if not path.exists():
        raise PilotlabError(f"{artifact_dir}: not a pilotlab artifact (no {META_FILE}); "
                            "give the folder an optimize job wrote (or `pilotlab export` copied)")
    try:
        data = json.loads(path.read_text(encoding="utf-8"))
    except (OSError, ValueError) as error:   # UnicodeDecodeError and JSONDecodeError are ValueErrors
        raise PilotlabError(f"{path}: not readable JSON ({type(error).__name__}: {error}); "
                            "rerun the optimize job that wrote it (or export it again)") from None
    if not isinstance(data, dict) or data.get("artifact_format") != ARTIFACT_FORMAT:
        found = data.get("artifact_format") if isinstance(data, dict) else type(data).__name__
        raise PilotlabError(f"{path}: artifact format {found!r} is not "
                            f"{ARTIFACT_FORMAT!r}; rerun the optimize job with this pilotlab")
    try:
        meta = ArtifactMeta.from_json(data)
    except (KeyError, TypeError) as error:
        raise PilotlabError(f"{path}: a damaged artifact.json ({type(error).__name__}: {error} missing or "
                            "of the wrong type); rerun the optimize job that wrote it") from None
    _check_file_name(path, meta.file)
    return meta


def _check_file_name(path: Path, name: Any) -> None:
    """The model file is a plain name inside the artifact's folder, never a path out of it."""
    if not isinstance(name, str) or not name or Path(name).name != name or name in (".", ".."):
        raise PilotlabError(f"{path}: \"file\": {name!r} is not a file name in the artifact's folder; "
                            "rerun the optimize job that wrote it")


def artifact_size_mb(artifact_dir: Path) -> float:
    """Size on disk of everything but artifact.json (the model file and any weight files)."""
    return sum(p.stat().st_size for p in _model_files(artifact_dir)) / 2**20


def _model_files(artifact_dir: Path) -> list[Path]:
    return sorted(p for p in Path(artifact_dir).rglob("*") if p.is_file() and p.name != META_FILE)


def artifact_size_gz_mb(artifact_dir: Path, level: int = 6) -> float:
    """Size of the same files gzip-compressed (each on its own, DEFLATE at `level`): how TF-MOT shows
    what pruning (runs of zeros) and clustering (few distinct values) buy, which the raw size hides.
    Level 6 is zlib's default, the one TF-MOT's guides zip at; level 9 took 6x as long on a pruned
    6 MB model (5.1 s against 0.8 s) for a file 2 % smaller."""
    total = 0
    for path in _model_files(artifact_dir):
        # a gzip member: 10-byte header + DEFLATE stream + 8-byte trailer (CRC32, size)
        compressor, size = zlib.compressobj(level, zlib.DEFLATED, -zlib.MAX_WBITS), 18
        with path.open("rb") as stream:
            for chunk in iter(lambda: stream.read(1 << 20), b""):
                size += len(compressor.compress(chunk))
        total += size + len(compressor.flush())
    return total / 2**20
