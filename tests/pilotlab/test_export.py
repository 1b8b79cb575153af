from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from matrix.store import Store
from pilotlab.cli import main
from pilotlab.errors import PilotlabError
from pilotlab.export import export_artifact
from pilotlab.predictor import load_predictor
from pilotlab.strategies.apply import StrategySource, apply_strategy


KEY = "ab12" + "0" * 60


@pytest.fixture(scope="module")
def store(trained, frames, tmp_path_factory):
    """The engine's store holding one optimize job, committed as the engine commits it."""
    store = Store(tmp_path_factory.mktemp("store"))
    work = store.new_workdir(KEY)
    value = apply_strategy("onnxruntime", {}, StrategySource(trained / "model.pt", work / "artifacts", (frames,)))
    store.commit(KEY, work, {"key": KEY, "kind": "optimize", "name": "optimize pilotnet/onnxruntime"},
                 {"status": "ok", "reason": "", "value": value})
    return store.root


def test_export_cli_copies_the_artifact_with_a_readme(store, tmp_path, capsys):
    out = tmp_path / "deploy"
    assert main(["export", "ab12", "--out", str(out), "--store", str(store)]) == 0
    readme = (out / "README.md").read_text()
    assert readme.startswith("# pilotnet/onnxruntime (pilotnet)\n")   # the recipe's model and strategy
    assert "onnxruntime.InferenceSession" in readme or "ort.InferenceSession" in readme
    assert "[N, 3, 66, 200]" in readme and "RGB in [0, 1]" in readme and "rad/s" in readme
    batch = np.random.default_rng(0).random((2, 3, 66, 200), dtype=np.float32)
    source = Store(store).artifacts(KEY)
    np.testing.assert_array_equal(load_predictor(out, "cpu1").predict(batch),
                                  load_predictor(source, "cpu1").predict(batch))


@pytest.mark.parametrize("interpolation", ["fast_area", "area", "linear"])
def test_the_readme_turns_a_camera_image_into_the_input_as_pilotlab_does(trained, frames, tmp_path, interpolation):
    from pilotlab.data.preprocess import PreprocessConfig, preprocess, to_input
    from pilotlab.export import readme
    from pilotlab.strategies.artifact import read_meta
    apply_strategy("onnxruntime", {}, StrategySource(trained / "model.pt", tmp_path / "a", (frames,)))
    config = PreprocessConfig(crop_top=0.4, crop_bottom=0.95, interpolation=interpolation)
    meta = dataclasses.replace(read_meta(tmp_path / "a"), preprocess={**vars(config), "frames": 1})
    code = readme(meta, {}).split("## From a camera image")[1].split("```python")[1].split("```")[0]
    namespace = {}
    exec(code, namespace)   # the README's own code, as a user would paste it
    camera = np.random.default_rng(0).integers(0, 256, (480, 640, 3), dtype=np.uint8)
    expected = to_input(preprocess(camera, config)[None]).numpy()
    np.testing.assert_allclose(namespace["camera_to_images"](camera), expected, atol=1e-7)


def test_export_errors_say_what_to_do(store, tmp_path, capsys):
    assert main(["export", "ffff", "--out", str(tmp_path / "x"), "--store", str(store)]) == 2
    assert "no job 'ffff'" in capsys.readouterr().err
    for key in ("[a-f]*", "/etc/passwd", "../../x", "ab1*"):
        assert main(["export", key, "--out", str(tmp_path / "x"), "--store", str(store)]) == 2
        err = capsys.readouterr().err
        assert "is not a job key" in err and len(err.strip().splitlines()) == 1
    assert not (tmp_path / "x").exists()
    other = Store(tmp_path / "other")
    key = "cd34" + "0" * 60
    other.commit(key, other.new_workdir(key), {"key": key, "kind": "offline", "name": "offline x"},
                 {"status": "ok", "reason": "", "value": {}})
    assert main(["export", key[:6], "--out", str(tmp_path / "x"), "--store", str(other.root)]) == 2
    assert "is an 'offline' job" in capsys.readouterr().err
    with pytest.raises(PilotlabError, match="not a pilotlab artifact"):
        export_artifact(tmp_path, {}, tmp_path / "y")


def test_export_to_an_existing_file_is_one_line(store, tmp_path, capsys):
    (tmp_path / "file").write_text("mine")
    assert main(["export", "ab12", "--out", str(tmp_path / "file"), "--store", str(store)]) == 2
    err = capsys.readouterr().err
    assert "is a file, not a folder; give --out a new folder" in err and len(err.strip().splitlines()) == 1
    assert (tmp_path / "file").read_text() == "mine"


def test_export_into_the_store_is_refused(store, capsys):
    """Outside test: `export KEY --out STORE/jobs/inside` wrote there; status then counted corrupt jobs
    and gc reported removing files it never removed."""
    assert main(["export", "ab12", "--out", str(store / "jobs" / "inside"), "--store", str(store)]) == 2
    err = capsys.readouterr().err
    assert "is inside the job store" in err and "outside it" in err and len(err.strip().splitlines()) == 1
    assert not (store / "jobs" / "inside").exists()


@pytest.mark.parametrize("kind, encoding", [("ros1", "rgb8"), ("ros1", "bgr8"), ("sqlite3", "rgb8"),
                                            ("sqlite3", "png")])
def test_the_readme_reads_camera_images_from_a_bag(store, tmp_path, kind, encoding):
    from pilotlab.export import FROM_A_BAG
    from tests.pilotlab.data.bagfiles import IMAGE_TOPIC, bag_path, drive_bag, images
    frames = images(3, height=48, width=64)
    path = bag_path(tmp_path, kind)
    drive_bag(path, kind, frames, encoding=encoding)
    namespace = {}
    exec(FROM_A_BAG.split("```python")[1].split("```")[0], namespace)   # the README's own code
    topic = IMAGE_TOPIC + ("/compressed" if encoding == "png" else "")
    read = [rgb for _, rgb in namespace["camera_images"](path, topic)]
    assert len(read) == 3 and all(np.array_equal(a, b) for a, b in zip(read, frames))


def test_the_readme_says_predict_is_normalised_and_how_to_get_v_and_w(store, tmp_path):
    from pilotlab.data.frames import LabelRanges
    out = tmp_path / "deploy"
    assert main(["export", "ab12", "--out", str(out), "--store", str(store)]) == 0
    text = " ".join((out / "README.md").read_text().split())
    assert "the same normalised `vw`" in text and "not speeds" in text and "## Camera images from a recorded bag" in text
    predictor = load_predictor(out, "cpu1")
    vw = predictor.predict(np.random.default_rng(1).random((1, 3, 66, 200), dtype=np.float32))
    v, w = LabelRanges.from_dict(predictor.meta.labels).denormalise(vw)[0]
    (v_lo, v_hi), (w_lo, w_hi) = predictor.meta.labels["v"], predictor.meta.labels["w"]
    assert v == pytest.approx(vw[0, 0] * (v_hi - v_lo) + v_lo, rel=1e-5)
    assert w == pytest.approx(vw[0, 1] * (w_hi - w_lo) + w_lo, rel=1e-5)


@pytest.mark.parametrize("strategy", ["litert_full_int8", "litert_int8"])
def test_the_readme_runs_an_edge_artifact_with_its_runtime_alone(artifacts, tmp_path, monkeypatch, strategy):
    """The README's own "Load and run" code (the LiteRT interpreter, no pilotlab, no TensorFlow)
    gives what pilotlab's predictor gives: for the integer-only model that includes (de)quantizing."""
    folder, value = artifacts[strategy]          # (the strategy applied once for every test: conftest.py)
    if isinstance(value, str):
        pytest.skip(value)
    out = export_artifact(folder, value, tmp_path / "deploy")
    text = (out / "README.md").read_text()
    code = text.split("## Load and run")[1].split("```python")[1].split("```")[0]
    images = np.random.default_rng(0).random((20, 3, 66, 200), dtype=np.float32)
    namespace = {"images": images}
    monkeypatch.chdir(out)              # the README names the model file relative to its folder
    exec(code, namespace)               # the README's own code, as a user would paste it
    np.testing.assert_allclose(namespace["vw"], load_predictor(out, "cpu1").predict(images), atol=1e-6)


def test_an_artifact_changed_since_its_job_is_not_exported_and_status_counts_it(store, tmp_path, capsys):
    """Outside test: one byte of a stored model.onnx overwritten, `export` shipped it (exit 0) and
    `status` said corrupt 0, while `plan` had the job stale ("output changed")."""
    import shutil
    copy = Store(shutil.copytree(store, tmp_path / "store"))
    model = next(p for p in copy.artifacts(KEY).iterdir() if p.suffix == ".onnx")
    data = bytearray(model.read_bytes())
    data[len(data) // 2] ^= 0xFF                       # the same size: only the sha256 tells
    model.write_bytes(bytes(data))
    assert main(["status", "--store", str(copy.root)]) == 0
    row = next(line.split() for line in capsys.readouterr().out.splitlines() if line.split()[:1] == ["optimize"])
    assert row == ["optimize", "0", "0", "1"]          # ok, not applicable, corrupt
    assert main(["export", "ab12", "--out", str(tmp_path / "deploy"), "--store", str(copy.root)]) == 2
    err = capsys.readouterr().err
    assert "is not the one the job wrote" in err and "rebuilds it" in err and len(err.strip().splitlines()) == 1
    assert not (tmp_path / "deploy").exists()
