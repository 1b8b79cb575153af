"""pilotlab's errors all derive from the engine's single root, `matrix.errors.MatrixError`."""
from matrix.errors import MatrixError, RecipeError, UnknownNameError  # noqa: F401  (re-exported)


class PilotlabError(MatrixError):
    """Something the user can fix: a bad bag, a missing topic, an unusable checkpoint..."""


class BagError(PilotlabError):
    """A rosbag (or dataset folder) cannot be read as asked; the message names the bag and topic."""


def library_message(error: BaseException, limit: int = 300) -> str:
    """A third-party error's message on one line, cut at `limit`: ONNX Runtime puts its reason on the
    line after 'Load model from ... failed:', so the first line alone says nothing."""
    return " ".join(line.strip() for line in str(error).splitlines() if line.strip())[:limit]
