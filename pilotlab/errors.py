"""pilotlab's errors all derive from the engine's single root, `matrix.errors.MatrixError`."""
import re

from matrix.errors import MatrixError, RecipeError, UnknownNameError  # noqa: F401  (re-exported)


class PilotlabError(MatrixError):
    """Something the user can fix: a bad bag, a missing topic, an unusable checkpoint..."""


class BagError(PilotlabError):
    """A rosbag (or dataset folder) cannot be read as asked; the message names the bag and topic."""


def library_message(error: BaseException, limit: int = 300) -> str:
    """A third-party error's message on one line, cut at `limit`: ONNX Runtime puts its reason on the
    line after 'Load model from ... failed:', so the first line alone says nothing, and before its reason
    the C++ source line and function signature, which alone could fill `limit` (on a GPU machine an
    IR-version refusal was cut before 'Unsupported model IR version')."""
    text = " ".join(line.strip() for line in str(error).splitlines() if line.strip())
    return clipped(_CPP_LOCATION.sub(" ", text), limit)


def clipped(text: str, limit: int) -> str:
    """`text` in at most `limit` characters: cut at the last space in the final stretch, with "…" to say
    so (a cut mid-word, as 'the checkpoint file is corru', read like the message itself)."""
    if len(text) <= limit:
        return text
    cut = text[:limit - 1]
    space = cut.rfind(" ")
    return (cut[:space] if space >= limit * 0.6 else cut).rstrip(" ,;:") + "…"


# "/onnxruntime_src/onnxruntime/core/graph/model.cc:256 onnxruntime::Model::Model(onnx::ModelProto&&, ...) "
# up to the signature's last ")" (with " const" or " [with T = ...]") before the reason's capital letter
_CPP_LOCATION = re.compile(r"\s*/\S+\.(?:cc|cpp|cu|h):\d+ .*?\)(?: const)?(?: \[with [^\]]*\])?\s+(?=[A-Z])")
