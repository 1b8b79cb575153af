"""Make the files recipes/own_network.yaml uses as "yours": the expert drives simple_circuit both ways
(with swerves), SmallPilotNet trains on it with pilotlab's training loop, and the trained network is
saved as a state dict (weights/small_pilotnet.pth) and as ONNX (weights/small_pilotnet.onnx).

    python examples/own_network/make_files.py          # about a minute on 2 cores

In real use these are the files you already have: a .pth saved with torch.save(model.state_dict()),
an ONNX graph exported from PyTorch or converted from TensorFlow."""
from __future__ import annotations

import sys
import tempfile
import warnings
from pathlib import Path

import torch

HERE = Path(__file__).resolve().parent
LABELS = {"v": [0.0, 14.0], "w": [-2.0, 2.0]}      # the ranges the recipe's `labels:` repeats


def recordings(folder: Path):
    from pilotlab.data.bags import read_frames
    from pilotlab.data.frames import FrameSet
    from pilotlab.sim.record import record
    from pilotlab.specs.frames import PreprocessConfig
    from pilotlab.specs.record import RecordSpec
    sets = []
    for seed, direction in enumerate(("cw", "ccw")):
        out = folder / f"{direction}.bag"
        record(RecordSpec(circuit="simple_circuit", direction=direction, laps=1, noise=0.1, seed=seed,
                          format="ros1"), out)
        sets.append(read_frames(out, PreprocessConfig()))
    return FrameSet.concat(sets)


def main() -> None:
    sys.path.insert(0, str(HERE))
    from small_pilotnet import SmallPilotNet

    from pilotlab.data.frames import LabelRanges
    from pilotlab.training import FitConfig, FitProgress, fit
    torch.manual_seed(0)
    with tempfile.TemporaryDirectory() as tmp:
        data = recordings(Path(tmp))
    model = SmallPilotNet(width=8)
    config = FitConfig(epochs=15, batch_size=32, lr=2e-3, augment=_flip())
    with FitProgress(config.epochs, "SmallPilotNet") as bar:
        fit(model, data, LabelRanges.from_dict(LABELS), config, on_epoch=bar.on_epoch, on_batch=bar.on_batch)
    (HERE / "weights").mkdir(exist_ok=True)
    torch.save(model.state_dict(), HERE / "weights/small_pilotnet.pth")
    export_onnx(model)
    print(f"wrote {HERE / 'weights'}/small_pilotnet.pth and .onnx from {len(data)} frames")


def export_onnx(model) -> None:
    """As a user would: torch.onnx.export with their own input and output names and a dynamic batch."""
    batch = torch.export.Dim("batch", min=1)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        program = torch.onnx.export(model.eval(), (torch.rand(2, 3, 66, 200),), dynamo=True, input_names=["image"],
                                    output_names=["v_w"], dynamic_shapes=({0: batch},), verbose=False)
    program.save(str(HERE / "weights/small_pilotnet.onnx"), external_data=False)


def _flip():
    from pilotlab.specs.train import AugmentConfig
    return AugmentConfig(flip=True)


if __name__ == "__main__":
    if sys.argv[1:] == ["--onnx-only"]:           # the .onnx again from the .pth
        sys.path.insert(0, str(HERE))
        from small_pilotnet import SmallPilotNet
        net = SmallPilotNet(width=8)
        net.load_state_dict(torch.load(HERE / "weights/small_pilotnet.pth", weights_only=True))
        export_onnx(net)
    else:
        main()
