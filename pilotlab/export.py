"""Copy an optimized artifact out of the job store, with a README saying how to deploy it."""
from __future__ import annotations

import json
import shutil
from pathlib import Path
from typing import Any

from matrix.store import INTACT, MISSING, Store
from pilotlab.errors import PilotlabError
from pilotlab.strategies.artifact import META_FILE, ArtifactMeta, read_meta

LOADERS = {
    "onnx": """```python
import numpy as np, onnxruntime as ort
session = ort.InferenceSession("{file}", providers=["CPUExecutionProvider"])
vw = session.run(["vw"], {{"images": images}})[0]      # images: float32 {shape}
```""",
    "torchscript": """```python
import torch
module = torch.jit.load("{file}").eval()
with torch.inference_mode():
    vw = module(torch.from_numpy(images){cast}).float().numpy()   # images: float32 {shape}
```""",
    "tflite": """```python
import numpy as np
from ai_edge_litert.interpreter import Interpreter    # pip install ai-edge-litert (no TensorFlow needed)
interpreter = Interpreter(model_path="{file}", num_threads=1)
inp, out = interpreter.get_input_details()[0], interpreter.get_output_details()[0]
interpreter.resize_tensor_input(inp["index"], list(images.shape))   # images: float32 {shape}
interpreter.allocate_tensors()
{quantize}interpreter.set_tensor(inp["index"], x)
interpreter.invoke()
vw = interpreter.get_tensor(out["index"]){dequantize}
```""",
    "pilotlab-checkpoint": """```python
import torch
from pilotlab.models import load_checkpoint          # needs pilotlab installed
model, checkpoint = load_checkpoint("{file}")
with torch.inference_mode():
    vw = model(torch.from_numpy(images)).numpy()      # images: float32 {shape}
```""",
}

RESIZES = {  # pilotlab.data.preprocess.resize, written out with OpenCV alone
    "fast_area": """    while image.shape[1] >= {w2} and image.shape[0] >= {h2}:   # 2x2 means while twice the size
        even = image[:image.shape[0] // 2 * 2, :image.shape[1] // 2 * 2]
        image = cv2.resize(even, (even.shape[1] // 2, even.shape[0] // 2), interpolation=cv2.INTER_AREA)
    image = cv2.resize(image, ({w}, {h}), interpolation=cv2.INTER_LINEAR)""",
    "area": "    image = cv2.resize(image, ({w}, {h}), interpolation=cv2.INTER_AREA)",
    "linear": "    image = cv2.resize(image, ({w}, {h}), interpolation=cv2.INTER_LINEAR)",
}
CAMERA_TO_IMAGES = """```python
import cv2, numpy as np

def camera_to_images(rgb):    # one HxWx3 uint8 RGB camera image -> float32 [1, 3, {h}, {w}]
    top, bottom = round({top} * rgb.shape[0]), round({bottom} * rgb.shape[0])
    image = rgb[top:max(bottom, top + 1)]
{resize}
    return image.transpose(2, 0, 1)[None].astype(np.float32) / np.float32(255)
```"""

FROM_A_BAG = """```python
from pathlib import Path

import cv2, numpy as np
from rosbags.highlevel import AnyReader                      # pip install rosbags
from rosbags.typesys import Stores, get_typestore

def camera_images(bag, topic="/F1ROS/cameraL/image_raw"):
    \"\"\"(stamp in ns, H×W×3 uint8 RGB) for each image of a ROS1 .bag or a ROS2 bag folder;
    give the .../compressed topic for jpeg/png frames.\"\"\"
    with AnyReader([Path(bag)], default_typestore=get_typestore(Stores.ROS2_HUMBLE)) as reader:
        connections = [c for c in reader.connections if c.topic == topic]
        for connection, stamp, raw in reader.messages(connections=connections):
            msg = reader.deserialize(raw, connection.msgtype)
            if connection.msgtype.endswith("CompressedImage"):   # jpeg/png decode to BGR
                bgr = cv2.imdecode(np.asarray(msg.data), cv2.IMREAD_COLOR)
                yield stamp, cv2.cvtColor(bgr, cv2.COLOR_BGR2RGB)
                continue
            rows = np.asarray(msg.data).reshape(msg.height, msg.step)[:, :msg.width * 3]
            pixels = rows.reshape(msg.height, msg.width, 3)       # sensor_msgs/Image rgb8 or bgr8
            yield stamp, pixels[..., ::-1] if msg.encoding == "bgr8" else pixels
```

Then, for each image: `vw = <run the model>(camera_to_images(rgb))` and denormalise as above to get
v (m/s) and w (rad/s)."""

FRAMEWORKS = {"onnx": "ONNX (run with ONNX Runtime ≥ 1.18, no Python needed in C/C++/C#/Java)",
              "torchscript": "TorchScript (run with PyTorch or libtorch in C++)",
              "pilotlab-checkpoint": "a pilotlab checkpoint (PyTorch eager; needs pilotlab)",
              "tflite": "TF Lite (run with the LiteRT interpreter, `ai-edge-litert`, or TF Lite in C++/Java/Kotlin)"}
QUANTIZE = """s, z = inp["quantization"]                            # integer-only: int8 in, int8 out
x = np.clip(np.round(images / s) + z, -128, 127).astype(np.int8)
"""
DEQUANTIZE = """
s, z = out["quantization"]
vw = (vw.astype(np.float32) - z) * s                  # read raw, the int8 output is meaningless"""


def export_artifact(artifact_dir: Path, result: dict[str, Any], out_dir: Path, name: str | None = None) -> Path:
    """Copy the artifact folder into `out_dir` and write README.md (titled `name`, the recipe's
    MODEL/STRATEGY, where known); returns out_dir."""
    artifact_dir, out_dir = Path(artifact_dir), Path(out_dir)
    meta = read_meta(artifact_dir)
    if out_dir.exists() and not out_dir.is_dir():
        raise PilotlabError(f"{out_dir} is a file, not a folder; give --out a new folder")
    if out_dir.exists() and any(out_dir.iterdir()):
        raise PilotlabError(f"{out_dir} exists and is not empty; give --out a new folder")
    shutil.copytree(artifact_dir, out_dir, dirs_exist_ok=True)
    (out_dir / "README.md").write_text(readme(meta, result, name))
    return out_dir


def readme(meta: ArtifactMeta, result: dict[str, Any], name: str | None = None) -> str:
    shape = "[N, " + ", ".join(str(d) for d in meta.input_shape[1:]) + "]"
    cast = {"bfloat16": ".bfloat16()", "float16": ".half()"}.get(meta.dtype, "")
    labels = meta.labels
    lines = [
        f"# {name} ({meta.arch})" if name else f"# {meta.arch} — {meta.strategy}", "",
        f"Exported from pilotlab: strategy `{meta.strategy}` (version {meta.strategy_version}), "
        f"{meta.dtype} weights, {FRAMEWORKS.get(meta.format, meta.format)}, for {meta.device}.", "",
        f"- File: `{meta.file}` ({result.get('size_mb', 0):.2f} MB); metadata: `{META_FILE}`.",
        f"- Input `images`: float32 {shape}, NCHW, RGB in [0, 1], any batch size N.",
        f"- Preprocessing of a camera image: {json.dumps(meta.preprocess) if meta.preprocess else 'see artifact.json'} "
        f"(pilotlab: lower half of the 640×480 image, resized to {meta.input_shape[3]}×{meta.input_shape[2]}, divided by 255).",
        f"- Output `vw`: float32 [N, 2], normalised (v, w). Physical value = x × (hi − lo) + lo with "
        f"v in [{labels['v'][0]}, {labels['v'][1]}] m/s and w in [{labels['w'][0]}, {labels['w'][1]}] rad/s.",
        "", "## Load and run", "",
        loader(meta, shape, cast), "",
        "Denormalise:", "", "```python",
        f"v = vw[:, 0] * ({labels['v'][1]} - {labels['v'][0]}) + {labels['v'][0]}",
        f"w = vw[:, 1] * ({labels['w'][1]} - {labels['w'][0]}) + {labels['w'][0]}", "```", "",
        "Or with pilotlab: `pilotlab.predictor.load_predictor(folder, 'cpu').predict(images)`. It returns the "
        "same normalised `vw` (float32 [N, 2], each in about [0, 1]), not speeds: denormalise it as above, or "
        "`pilotlab.data.frames.LabelRanges.from_dict(predictor.meta.labels).denormalise(vw)` gives "
        "[N, 2] (v m/s, w rad/s).", "",
        *source_section(meta), *camera_section(meta)]
    return "\n".join(lines)


def source_section(meta: ArtifactMeta) -> list[str]:
    """Where a model the user brought came from (pilotlab.models.imported), and what loading needs."""
    config = meta.config or {}
    if meta.arch == "network":
        needs = (" Loading the pilotlab checkpoint imports that class again: keep its file (and the modules "
                 "it imports) where it was." if meta.format == "pilotlab-checkpoint" else "")
        return ["## Where the network came from", "",
                f"Your class `{config.get('network')}` with options `{json.dumps(config.get('options', {}))}` "
                f"(source sha256 {str(config.get('source_hash', ''))[:12]}).{needs}", ""]
    if meta.arch in ("torchscript", "onnx"):
        return ["## Where the network came from", "",
                f"Your {meta.arch} file `{config.get('file')}` (sha256 {str(config.get('sha256', ''))[:12]}).", ""]
    return []


def loader(meta: ArtifactMeta, shape: str, cast: str) -> str:
    integer_only = "input_quantization" in meta.extra
    return LOADERS[meta.format].format(
        file=meta.file, shape=shape, cast=cast,
        quantize=QUANTIZE if integer_only else "x = images\n", dequantize=DEQUANTIZE if integer_only else "")


def camera_section(meta: ArtifactMeta) -> list[str]:
    """How to turn a camera image into `images` without pilotlab, as the network was trained."""
    pre = meta.preprocess or {}
    if pre.get("frames", 1) != 1 or pre.get("interpolation", "fast_area") not in RESIZES:
        return []
    height, width = meta.input_shape[2], meta.input_shape[3]
    resize = RESIZES[pre.get("interpolation", "fast_area")].format(w=width, h=height, w2=2 * width, h2=2 * height)
    return ["## From a camera image", "",
            CAMERA_TO_IMAGES.format(top=pre.get("crop_top", 0.0), bottom=pre.get("crop_bottom", 1.0),
                                    w=width, h=height, resize=resize), "",
            "## Camera images from a recorded bag", "",
            "pilotlab's recordings (and DeepLearningStudio's) keep the camera on `/F1ROS/cameraL/image_raw` "
            "(sensor_msgs/Image rgb8) or `/F1ROS/cameraL/image_raw/compressed` (jpeg/png); the expert's "
            "commands (the labels) are on `/F1ROS/cmd_vel` (Twist: `linear.x` = v, `angular.z` = w), "
            "stamped like the frame they answer.", "", FROM_A_BAG, ""]


def export_job(store: Store, key_prefix: str, out_dir: Path) -> Path:
    """Export the optimize job `key_prefix` (a unique prefix is enough) from the engine's store."""
    key = store.find(key_prefix)
    if Path(out_dir).resolve().is_relative_to(store.root.resolve()):
        raise PilotlabError(f"--out {out_dir} is inside the job store {store.root}, which pilotlab keeps for itself "
                            "(gc would take the files for jobs); export to a folder outside it")
    spec, stored = store.spec(key) or {}, store.result(key)
    if stored is None:
        raise PilotlabError(f"job {key[:12]} has no result (it failed or has not run; "
                            "`pilotlab plan RECIPE` shows each job's state and key)")
    if spec.get("kind") != "optimize":
        kind = str(spec.get("kind"))
        raise PilotlabError(f"job {key[:12]} is {'an' if kind[:1] in 'aeiou' else 'a'} {kind!r} job "
                            f"({spec.get('name', '')}); "
                            "export the key of an optimize job (`pilotlab plan RECIPE` lists them)")
    if stored.get("status") != "ok":
        raise PilotlabError(f"job {key[:12]} ({spec.get('name', '')}) produced no artifact: "
                            f"{stored.get('status')}: {stored.get('reason', '')}")
    outputs = store.outputs_state(key, stored, full=True)   # every file against its recorded sha256
    if outputs != INTACT:
        what = "missing" if outputs == MISSING else "not the one the job wrote (its sha256 differs)"
        raise PilotlabError(f"job {key[:12]} ({spec.get('name', '')}): a file of its artifacts is {what}, so "
                            "nothing is exported; `pilotlab run RECIPE` rebuilds it")
    name = str(spec.get("name", "")).removeprefix("optimize ") or None   # the recipe's MODEL/STRATEGY
    return export_artifact(store.artifacts(key), stored.get("value") or {}, out_dir, name)
