"""Driving networks: camera image(s) -> normalised (v, w). Importing this package registers them."""
from pilotlab.models import pilotnet  # noqa: F401  (registers "pilotnet")
from pilotlab.models.registry import (  # noqa: F401
    MODELS, build_model, load_checkpoint, make_config, register_model, save_checkpoint,
)
