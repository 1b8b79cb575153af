"""Models the user brings (recipe `models:` with network / weights / torchscript / onnx), through the
real train, optimize and offline handlers on small random frames."""
from __future__ import annotations

import json
import warnings

import pytest
import torch

import pilotlab.jobs.optimize  # noqa: F401  (registers the kinds)
import pilotlab.jobs.prepare  # noqa: F401
import pilotlab.jobs.train  # noqa: F401
from matrix.kinds import KINDS, NotApplicable
from pilotlab import offline
from pilotlab.data.frames import FrameSet
from pilotlab.errors import PilotlabError
from pilotlab.export import export_artifact
from pilotlab.hardware import BUILTIN
from pilotlab.models import load_checkpoint
from tests.pilotlab.conftest import random_frames
from tests.pilotlab.jobs.context import context, finished
from tests.pilotlab.models.user_networks import DLS_OPTIONS, DLS_PILOTNET, load_class, write

LABELS = {"v": [0.0, 12.0], "w": [-1.5, 1.5]}
QUICK = offline.TimingSettings(warmup_runs=1, warmup_seconds=0.0, min_runs=3, max_runs=3, max_seconds=0.1,
                               block_seconds=0.01, min_blocks=1, attempts=1, throughput_min_runs=1,
                               throughput_seconds=0.05)


@pytest.fixture(scope="module")
def dls(tmp_path_factory):
    """DLS's PilotNet as the user has it: the class's file, a state dict, the same as TorchScript and ONNX."""
    folder = tmp_path_factory.mktemp("user")
    net_file = write(folder, "nets/pilotnet.py", DLS_PILOTNET)
    torch.manual_seed(3)
    model = load_class(net_file, "PilotNet")(**DLS_OPTIONS).eval()
    with torch.no_grad():   # a state as after training: the input norm's statistics are not the defaults
        model.ln_1.running_mean.uniform_(0.3, 0.6)
        model.ln_1.running_var.uniform_(0.05, 0.1)
    torch.save(model.state_dict(), folder / "pilot_net_model_best_123.pth")
    example = torch.rand(1, 3, 66, 200)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        torch.jit.save(torch.jit.trace(model, example), str(folder / "pilotnet.pt"))
        torch.onnx.export(model, (example,), str(folder / "pilotnet.onnx"), dynamo=False, input_names=["img"],
                          output_names=["out"], dynamic_axes={"img": {0: "n"}, "out": {0: "n"}})
    return folder


def run(tmp_path, kind, name, params, deps=None, inputs=None):
    ctx = context(tmp_path, kind, name, params, deps=deps, inputs=inputs)
    result = KINDS.get(kind).handler(ctx)
    json.dumps(result)
    return finished(ctx, result)


def _frames(folder, name):
    from matrix.kinds import DepResult
    return DepResult(key=name, kind="frames", params={}, result={}, artifacts=folder, name=name)


def train(tmp_path, frames, name, params, inputs):
    return run(tmp_path, "train", f"train {name}", {"labels": LABELS, "epochs": 1, "batch_size": 16, **params},
               deps={"frames": (_frames(frames, "frames"),)}, inputs=inputs)


def offline_mse(model, test_frames, exports) -> float:
    """The baseline artifact's offline MSE; `pilotlab export`'s README of it goes into `exports`."""
    artifact = run(model.artifacts.parent, "optimize", f"optimize {model.name}", {"strategy": "baseline"},
                   deps={"model": model})
    out = export_artifact(artifact.artifacts, artifact.result, model.artifacts.parent / f"export {model.name}")
    exports[model.name.removeprefix("train ")] = (out / "README.md").read_text()
    return offline.evaluate_offline(out, BUILTIN["cpu"], FrameSet.load(test_frames), QUICK)["mse"]


def test_a_dls_state_dict_as_it_is_torchscript_and_onnx_give_the_same_mse(tmp_path, dls, frames, test_frames):
    forms = {
        "network": ({"network": "nets/pilotnet.py:PilotNet", "options": DLS_OPTIONS,
                     "weights": "pilot_net_model_best_123.pth", "train": False},
                    {"network_source": dls / "nets/pilotnet.py", "weights": dls / "pilot_net_model_best_123.pth"}),
        "scripted": ({"torchscript": "pilotnet.pt"}, {"torchscript": dls / "pilotnet.pt"}),
        "exported": ({"onnx": "pilotnet.onnx"}, {"onnx": dls / "pilotnet.onnx"}),
        # DLS's layer names load into pilotlab's own PilotNet too
        "builtin": ({"arch": "pilotnet", "weights": "pilot_net_model_best_123.pth", "train": False},
                    {"weights": dls / "pilot_net_model_best_123.pth"}),
    }
    models = {name: train(tmp_path, frames, name, params, inputs) for name, (params, inputs) in forms.items()}
    assert all(m.result["trained"] is False and m.result["epochs_run"] == 0 for m in models.values())
    assert models["network"].result["source"]["kind"] == "network"
    assert len(models["network"].result["source"]["sha256"]) == 64
    val = {name: m.result["val_mse"] for name, m in models.items()}
    assert max(val.values()) - min(val.values()) < 1e-4, val
    exports = {}
    mse = {name: offline_mse(m, test_frames, exports) for name, m in models.items()}
    assert max(mse.values()) - min(mse.values()) < 1e-4, mse
    assert f"Your class `{dls / 'nets/pilotnet.py'}:PilotNet` with options" in exports["network"]
    assert "Your onnx file" in exports["exported"] and "Your torchscript file" in exports["scripted"]
    assert models["exported"].result["source"]["sha256"][:12] in exports["exported"]
    for model in models.values():   # checkpoints are plain data
        payload = torch.load(model.artifacts / "model.pt", map_location="cpu", weights_only=True)
        assert payload["arch"] in ("network", "torchscript", "onnx", "pilotnet")
    for name, file in (("scripted", "pilotnet.pt"), ("exported", "pilotnet.onnx")):   # the file once, not its weights again
        payload = torch.load(models[name].artifacts / "model.pt", map_location="cpu", weights_only=True)
        assert list(payload["state_dict"]) == ["program"]
        assert (models[name].artifacts / "model.pt").stat().st_size < 1.1 * (dls / file).stat().st_size


def test_a_network_class_trains_and_fine_tunes_from_weights(tmp_path, dls, frames):
    inputs = {"network_source": dls / "nets/pilotnet.py"}
    fresh = train(tmp_path, frames, "fresh", {"network": "nets/pilotnet.py:PilotNet", "options": DLS_OPTIONS},
                  inputs)
    tuned = train(tmp_path, frames, "tuned", {"network": "nets/pilotnet.py:PilotNet", "options": DLS_OPTIONS,
                                              "weights": "w.pth"},
                  {**inputs, "weights": dls / "pilot_net_model_best_123.pth"})
    for model in (fresh, tuned):
        assert model.result["trained"] is True and model.result["epochs_run"] == 1
        network, checkpoint = load_checkpoint(model.artifacts / "model.pt")
        assert type(network).__name__ == "PilotNet" and "fc_5.weight" in checkpoint["state_dict"]
        assert checkpoint["config"]["options"] == DLS_OPTIONS
    assert tuned.result["source"]["weights_sha256"]


def test_strategies_run_on_user_models_or_say_why_not(tmp_path, dls, frames):
    network = train(tmp_path, frames, "net", {"network": "nets/pilotnet.py:PilotNet", "options": DLS_OPTIONS,
                                              "weights": "w.pth", "train": False},
                    {"network_source": dls / "nets/pilotnet.py", "weights": dls / "pilot_net_model_best_123.pth"})
    graph = train(tmp_path, frames, "graph", {"onnx": "pilotnet.onnx"}, {"onnx": dls / "pilotnet.onnx"})
    frames_deps = (_frames(frames, "frames"),)

    def optimize(model, strategy):
        return run(tmp_path, "optimize", f"optimize {model.name}/{strategy}", {"strategy": strategy},
                   deps={"model": model, "calibration": frames_deps})
    assert optimize(network, "dynamic_quant").result["format"] == "onnx"
    assert optimize(network, "local_prune").result["sparsity"] > 0.2
    assert optimize(graph, "dynamic_quant").result["dtype"] == "int8"
    assert optimize(graph, "onnxruntime").result["format"] == "onnx"
    with pytest.raises(NotApplicable, match="local_prune works on a PyTorch network, not on the ONNX graph pilotnet.onnx"):
        optimize(graph, "local_prune")
    scripted = train(tmp_path, frames, "scripted", {"torchscript": "pilotnet.pt"}, {"torchscript": dls / "pilotnet.pt"})
    assert optimize(scripted, "dynamic_quant").result["dtype"] == "int8"   # through the TorchScript ONNX exporter
    with pytest.raises(NotApplicable, match="local_prune cannot work on the TorchScript model pilotnet.pt .it rewrites "
                                            "nn.Module layers"):
        optimize(scripted, "local_prune")
    with pytest.raises(NotApplicable, match="structured_prune removes channels from a PyTorch network's layers; a "
                                            "TorchScript model is run as it is"):   # read "needs two layers" (it has 5)
        optimize(scripted, "structured_prune")

    def prepare(model):   # the network structured_prune's rows convert, pruned once for them all in a run
        return run(tmp_path, "prepare", f"prepare {model.name}/channel_pruning", {"preparation": "channel_pruning"},
                   deps={"model": model, "calibration": frames_deps})
    with pytest.raises(NotApplicable, match="structured_prune removes channels from a PyTorch network's layers"):
        prepare(scripted)
    with pytest.raises(NotApplicable, match="channel_pruning works on a PyTorch network, not on the ONNX graph"):
        prepare(graph)
    pooled = torch.nn.Sequential(torch.nn.Conv2d(3, 4, 5, stride=2), torch.nn.AdaptiveAvgPool2d((1, 8)),
                                 torch.nn.Flatten(), torch.nn.Linear(32, 2)).eval()
    torch.jit.trace(pooled, torch.rand(1, 3, 66, 200)).save(tmp_path / "pooled.pt")   # 98 is no multiple of 8
    unexportable = train(tmp_path, frames, "pooled", {"torchscript": "pooled.pt"}, {"torchscript": tmp_path / "pooled.pt"})
    with pytest.raises(NotApplicable, match=r"dynamic_quant cannot work on the TorchScript model pooled.pt \(its ONNX "
                                            r"export, which this strategy starts from, failed\): .*adaptive_avg_pool2d"):
        optimize(unexportable, "dynamic_quant")


# --- bad input: one line naming the recipe key ------------------------------------------------------

def error_of(tmp_path, frames, params, inputs) -> str:
    with pytest.raises(PilotlabError) as caught:
        train(tmp_path, frames, "mine", params, inputs)
    message = str(caught.value)
    assert "\n" not in message
    return message


def test_options_the_class_does_not_take(tmp_path, dls, frames):
    message = error_of(tmp_path, frames, {"network": "nets/pilotnet.py:PilotNet", "options": {"image_shape": [200, 66, 3],
                                                                                               "labels": 2}},
                       {"network_source": dls / "nets/pilotnet.py"})
    assert message == ("models.mine.options: PilotNet(image_shape, num_labels) does not take labels "
                       "(did you mean 'num_labels'?)")


def test_no_such_class(tmp_path, dls, frames):
    message = error_of(tmp_path, frames, {"network": "nets/pilotnet.py:PilotNett"},
                       {"network_source": dls / "nets/pilotnet.py"})
    assert message.startswith("models.mine.network: ") and "has no 'PilotNett'" in message
    assert "did you mean 'PilotNet'" in message


def test_an_exception_in_the_network_file_names_its_line(tmp_path, frames):
    path = write(tmp_path, "broken.py", "import torch\n\n\nraise ValueError('half written')\n")
    message = error_of(tmp_path, frames, {"network": "broken.py:Net"}, {"network_source": path})
    assert message.startswith("models.mine.network: ") and f"{path}:4: ValueError: half written" in message


def test_weights_that_do_not_fit(tmp_path, dls, frames):
    other = write(tmp_path, "other.py", DLS_PILOTNET.replace("self.fc_5 = ", "self.extra = nn.Linear(10, 10)\n"
                                                             "        self.fc_5 = ").replace("1164", "1000"))
    message = error_of(tmp_path, frames, {"network": "other.py:PilotNet", "options": DLS_OPTIONS, "weights": "w.pth"},
                       {"network_source": other, "weights": dls / "pilot_net_model_best_123.pth"})
    assert message.startswith("models.mine.weights: pilot_net_model_best_123.pth does not fit PilotNet: ")
    assert "missing keys extra.weight, extra.bias" in message
    assert "first shape that differs: fc_1.weight is [1164, 1152] in the file, [1000, 1152] in the network" in message


def test_dls_weights_read_under_pilotlab_s_names_say_so(tmp_path, dls, frames):
    """Outside test: DLS weights into another network listed keys the file does not hold (input_norm.*,
    pilotlab's names for its ln_1.*) without a word of the renaming."""
    tiny = write(tmp_path, "tiny.py", "import torch.nn as nn\n\n\nclass Tiny(nn.Module):\n    def __init__(self):\n"
                 "        super().__init__()\n        self.c = nn.Conv2d(3, 2, 3)\n\n    def forward(self, x):\n"
                 "        return self.c(x).mean((2, 3))\n")
    message = error_of(tmp_path, frames, {"network": "tiny.py:Tiny", "weights": "w.pth"},
                       {"network_source": tiny, "weights": dls / "pilot_net_model_best_123.pth"})
    assert "unexpected keys input_norm." in message
    assert message.endswith("(the file's DeepLearningStudio PilotNet names read as pilotlab's: ln_1 as input_norm, ...)")


def test_weights_that_are_not_a_state_dict(tmp_path, dls, frames):
    junk = tmp_path / "junk.pth"
    junk.write_bytes(b"not a torch file")
    message = error_of(tmp_path, frames, {"network": "nets/pilotnet.py:PilotNet", "options": DLS_OPTIONS,
                                          "weights": "junk.pth"},
                       {"network_source": dls / "nets/pilotnet.py", "weights": junk})
    assert message.startswith("models.mine.weights: junk.pth is not a state dict torch.load(weights_only=True)")
    # outside test: torch's advice to load it with weights_only=False (running the file's code) was passed on
    assert "weights_only` set to `False`" not in message and "Unsupported operand" in message


def test_weights_saved_as_a_whole_module_say_how_to_save_a_state_dict(tmp_path, dls, frames):
    net = load_class(dls / "nets/pilotnet.py", "PilotNet")(**DLS_OPTIONS)
    torch.save(net, tmp_path / "whole.pth")
    message = error_of(tmp_path, frames, {"network": "nets/pilotnet.py:PilotNet", "options": DLS_OPTIONS,
                                          "weights": "whole.pth"},
                       {"network_source": dls / "nets/pilotnet.py", "weights": tmp_path / "whole.pth"})
    assert message.startswith("models.mine.weights: whole.pth holds Python objects (")
    assert "torch.save(model.state_dict(), path)" in message and "\x1b" not in message


def test_an_output_that_is_not_n_by_2(tmp_path, dls, frames):
    message = error_of(tmp_path, frames, {"network": "nets/pilotnet.py:PilotNet",
                                          "options": {"image_shape": [200, 66, 3], "num_labels": 3}},
                       {"network_source": dls / "nets/pilotnet.py"})
    # outside test: every wrong output got the input-size hint, where the input was not the problem
    assert message == ("models.mine.network: PilotNet's output for an input [2, 3, 66, 200] is [2, 3]; a driving "
                       "network returns [N, 2] (normalised v, w): its last layer must give 2 outputs")


def test_an_output_of_two_tensors_says_how_to_return_one(tmp_path, frames):
    write(tmp_path, "nets/pair.py", "import torch\n\n\nclass Pair(torch.nn.Module):\n    def __init__(self):\n"
                                    "        super().__init__()\n        self.fc = torch.nn.Linear(1, 2)\n\n"
                                    "    def forward(self, x):\n        out = self.fc(x.mean((1, 2, 3))[:, None])\n"
                                    "        return out[:, 0], out[:, 1]\n")
    message = error_of(tmp_path, frames, {"network": "nets/pair.py:Pair"}, {"network_source": tmp_path / "nets/pair.py"})
    assert message.endswith("output for an input [2, 3, 66, 200] is a tuple; a driving network returns one tensor "
                            "[N, 2] (normalised v, w); return torch.stack([v, w], 1)")


def test_a_network_without_forward_is_said_once(tmp_path, frames):
    """Outside test: "models.mine.network: Net fails ...: models.mine.network: Net: NotImplementedError" (no
    line of the user's: the key path was said again in its place)."""
    write(tmp_path, "nets/no_forward.py", "import torch\n\n\nclass Net(torch.nn.Module):\n    pass\n")
    message = error_of(tmp_path, frames, {"network": "nets/no_forward.py:Net"},
                       {"network_source": tmp_path / "nets/no_forward.py"})
    assert message.count("models.mine.network") == 1 and \
        "(the preprocessed camera image): NotImplementedError: Module [Net] is missing" in message


def test_a_general_checkpoint_s_state_dict_is_unwrapped(tmp_path, dls, frames):
    """Outside test: a file saved as PyTorch's tutorial saves a general checkpoint, {"epoch": 3,
    "model_state_dict": ...}, was "not a state dict"."""
    state = torch.load(dls / "pilot_net_model_best_123.pth", weights_only=True)
    torch.save({"epoch": 3, "model_state_dict": state, "loss": 0.1}, tmp_path / "general.pth")
    params = {"network": "nets/pilotnet.py:PilotNet", "options": DLS_OPTIONS, "weights": "general.pth"}
    train(tmp_path, frames, "general", params, {"network_source": dls / "nets/pilotnet.py", "weights": tmp_path / "general.pth"})
    torch.save({"epoch": 3, "weights": state}, tmp_path / "odd.pth")
    message = error_of(tmp_path, frames, params | {"weights": "odd.pth"},
                       {"network_source": dls / "nets/pilotnet.py", "weights": tmp_path / "odd.pth"})
    assert "odd.pth is not a state dict (a mapping of names to tensors) (it holds epoch, weights)" in message


def test_a_network_that_fails_on_the_input_size(tmp_path, dls):
    import numpy as np
    narrow = random_frames(8, seed=4)   # preprocessed to 100x66, where the network wants 200x66
    narrow = FrameSet(np.ascontiguousarray(narrow.frames[:, :, :100]), narrow.labels, narrow.recording,
                      {"preprocess": {"width": 100, "height": 66}})
    narrow.save(tmp_path / "narrow")
    message = error_of(tmp_path, tmp_path / "narrow", {"network": "nets/pilotnet.py:PilotNet", "options": DLS_OPTIONS,
                                                       "preprocess": {"width": 100, "height": 66}},
                       {"network_source": dls / "nets/pilotnet.py"})
    assert message.startswith("models.mine.network: PilotNet fails on an input [2, 3, 66, 100] (the preprocessed "
                              "camera image): ")
    assert "RuntimeError" in message


def test_an_onnx_file_that_is_not_a_model(tmp_path, frames):
    junk = tmp_path / "model.onnx"
    junk.write_bytes(b"\x08\x07garbage that protobuf will not take" * 3)
    message = error_of(tmp_path, frames, {"onnx": "model.onnx"}, {"onnx": junk})
    assert message.startswith("models.mine.onnx: model.onnx is not an ONNX model (")


def test_an_onnx_graph_fixed_at_one_batch_size_is_refused_with_the_export_that_fixes_it(tmp_path, dls, frames):
    """torch.onnx.export's default fixes the batch axis at the example's; the graph would fail at batch 64
    (ONNX Runtime: 'Got invalid dimensions for input')."""
    net = load_class(dls / "nets/pilotnet.py", "PilotNet")(**DLS_OPTIONS).eval()
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        torch.onnx.export(net, (torch.rand(1, 3, 66, 200),), str(tmp_path / "fixed.onnx"), dynamo=False)
    message = error_of(tmp_path, frames, {"onnx": "fixed.onnx"}, {"onnx": tmp_path / "fixed.onnx"})
    assert message.startswith("models.mine.onnx: fixed.onnx: its input 'input.1' has a fixed batch size of 1 "
                              "([1, 3, 66, 200]);")
    assert "dynamic_axes" in message and "\n" not in message


def test_an_onnx_input_is_named_as_in_the_user_s_file(tmp_path, dls, frames):
    """Outside test: named 'images', as the fixed-batch message itself advises, it read 'user/images'."""
    net = load_class(dls / "nets/pilotnet.py", "PilotNet")(**DLS_OPTIONS).eval()
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        torch.onnx.export(net, (torch.rand(1, 3, 66, 200),), str(tmp_path / "named.onnx"), dynamo=False,
                          input_names=["images"], output_names=["vw"])
    named = error_of(tmp_path, frames, {"onnx": "named.onnx"}, {"onnx": tmp_path / "named.onnx"})
    assert "its input 'images' has a fixed batch size" in named


class _Nhwc(torch.nn.Module):
    """The same network taking [N, H, W, C], as TensorFlow exports it."""

    def __init__(self, inner):
        super().__init__()
        self.inner = inner

    def forward(self, images):
        return self.inner(images.permute(0, 3, 1, 2))


@pytest.mark.parametrize("layout", ["NCHW", "NHWC"])
def test_an_onnx_model_already_named_images_and_vw(tmp_path, dls, frames, layout):
    """The most natural export names its input `images` and its output `vw`, as pilotlab does."""
    torch.manual_seed(3)
    net = load_class(dls / "nets/pilotnet.py", "PilotNet")(**DLS_OPTIONS).eval()
    exported = _Nhwc(net) if layout == "NHWC" else net
    example = torch.rand(1, 66, 200, 3) if layout == "NHWC" else torch.rand(1, 3, 66, 200)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        torch.onnx.export(exported, (example,), str(tmp_path / "m.onnx"), dynamo=False, input_names=["images"],
                          output_names=["vw"], dynamic_axes={"images": {0: "n"}, "vw": {0: "n"}})
    model = train(tmp_path, frames, "graph", {"onnx": "m.onnx"}, {"onnx": tmp_path / "m.onnx"})
    loaded, _ = load_checkpoint(model.artifacts / "model.pt")
    batch = torch.rand(2, 3, 66, 200)
    with torch.no_grad():
        torch.testing.assert_close(loaded(batch), net(batch), atol=1e-4, rtol=1e-4)


def onnx_with_external_data(folder, net, location="sub/local.bin"):
    """models/m.onnx keeping its weights in `location`, relative to models/ (onnx.save_model writes it there)."""
    import onnx
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        torch.onnx.export(net, (torch.rand(1, 3, 66, 200),), str(folder / "whole.onnx"), dynamo=False,
                          input_names=["img"], output_names=["out"], dynamic_axes={"img": {0: "n"}, "out": {0: "n"}})
    (folder / "models" / location).parent.mkdir(parents=True, exist_ok=True)
    onnx.save_model(onnx.load(str(folder / "whole.onnx")), str(folder / "models/m.onnx"), save_as_external_data=True,
                    location=location, size_threshold=0)
    return folder / "models/m.onnx"


def test_onnx_external_data_is_read_beside_the_model_not_in_the_current_folder(tmp_path, dls, frames, monkeypatch):
    torch.manual_seed(4)
    net = load_class(dls / "nets/pilotnet.py", "PilotNet")(**DLS_OPTIONS).eval()
    (tmp_path / "user").mkdir()
    path = onnx_with_external_data(tmp_path / "user", net)
    elsewhere = tmp_path / "elsewhere"
    elsewhere.mkdir()
    monkeypatch.chdir(elsewhere)
    model = train(tmp_path, frames, "graph", {"onnx": "models/m.onnx"}, {"onnx": path})
    (path.parent / "sub/local.bin").unlink()     # the checkpoint holds the weights: it needs no file beside it
    loaded, _ = load_checkpoint(model.artifacts / "model.pt")
    batch = torch.rand(2, 3, 66, 200)
    with torch.no_grad():
        torch.testing.assert_close(loaded(batch), net(batch), atol=1e-4, rtol=1e-4)
    message = error_of(tmp_path, frames, {"onnx": "models/m.onnx"}, {"onnx": path})
    assert message.startswith("models.mine.onnx: ") and "keeps its data in 'sub/local.bin', which is not a file" in message


def test_onnx_external_data_outside_the_models_folder_is_refused(tmp_path, dls, frames):
    import onnx
    net = load_class(dls / "nets/pilotnet.py", "PilotNet")(**DLS_OPTIONS).eval()
    path = onnx_with_external_data(tmp_path, net, location="outside.bin")
    (path.parent / "outside.bin").rename(tmp_path / "outside.bin")
    model = onnx.load(str(path), load_external_data=False)
    for tensor in model.graph.initializer:
        for entry in tensor.external_data:
            entry.value = "../outside.bin" if entry.key == "location" else entry.value
    path.write_bytes(model.SerializeToString())
    message = error_of(tmp_path, frames, {"onnx": "models/m.onnx"}, {"onnx": tmp_path / "models/m.onnx"})
    assert message.startswith("models.mine.onnx: ") and "outside the model file's folder; refused" in message


def test_a_file_that_is_no_torchscript_says_what_one_is(tmp_path, frames):
    """Outside test: an ONNX file given as torchscript passed on miniz's talk of corrupted checkpoints."""
    (tmp_path / "model.onnx").write_bytes(b"\x08\x07" + b"onnx-ish bytes" * 20)
    message = error_of(tmp_path, frames, {"torchscript": "model.onnx", "labels": {"v": [0, 1], "w": [-1, 1]}},
                       {"torchscript": tmp_path / "model.onnx"})
    assert message.endswith("model.onnx is not a TorchScript model torch.jit.load can read: PytorchStreamReader "
                            "failed reading zip archive: failed finding central directory (a TorchScript file is the "
                            "zip archive torch.jit.save writes)")
