"""Driving networks: camera image(s) -> normalised (v, w). Importing this package registers them
(their configs: the networks, and torch, are imported when a model is built)."""
from pilotlab.models import configs  # noqa: F401  (registers "pilotnet", "pilotnet_stacked")
from pilotlab.models import imported  # noqa: F401  (registers the user models' "network", "torchscript", "onnx")
from pilotlab.models.registry import (  # noqa: F401
    MODELS, build_model, input_frames, load_checkpoint, make_config, register_model, save_checkpoint,
)
