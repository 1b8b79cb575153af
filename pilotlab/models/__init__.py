"""Driving networks: camera image(s) -> normalised (v, w). Importing this package registers them."""
from pilotlab.models import pilotnet  # noqa: F401  (registers "pilotnet")
from pilotlab.models import pilotnet_stacked  # noqa: F401  (registers "pilotnet_stacked")
from pilotlab.models.registry import (  # noqa: F401
    MODELS, build_model, input_frames, load_checkpoint, make_config, register_model, save_checkpoint,
)
