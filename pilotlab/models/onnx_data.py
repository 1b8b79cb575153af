"""The files an ONNX model keeps its weights in ("external data"): resolved against the model file's
folder (never the current one), and never outside that folder, links resolved. Used when planning
(each such file is an input of the train job), when importing a user's model (the weights are read
into the checkpoint) and before ONNX Runtime loads an artifact. onnx is imported only when called."""
from __future__ import annotations

from pathlib import Path

from pilotlab.errors import PilotlabError, clipped


def load_without_data(path: Path):
    """The ModelProto of `path`, its external data left unread; a one-line error if it is not ONNX."""
    import onnx
    try:
        return onnx.load(str(path), load_external_data=False)
    except Exception as error:  # protobuf's DecodeError, OSError, ...
        raise PilotlabError(f"{path}: not a readable ONNX model ({type(error).__name__}: "
                            f"{clipped((str(error).splitlines() or [''])[0], 200)})") from None


def external_data_files(model, path: Path, holder: str) -> dict[str, Path]:
    """{location as written: the file} of every tensor of `model` (read from `path`) kept outside it.
    A location outside the model's folder, or a file that is not there, is a one-line error;
    `holder` names that folder in it ("the artifact's folder")."""
    from onnx.external_data_helper import _get_all_tensors, uses_external_data
    folder = Path(path).parent.resolve()
    files = {}
    for tensor in _get_all_tensors(model):
        if not uses_external_data(tensor):
            continue
        location = next((entry.value for entry in tensor.external_data if entry.key == "location"), "")
        target = (folder / location).resolve()
        if not location or Path(location).is_absolute() or not target.is_relative_to(folder):
            raise PilotlabError(f"{path}: tensor {tensor.name!r} keeps its data in {location!r}, outside "
                                f"{holder}; refused (an exported model keeps its files together)")
        if not target.is_file():
            raise PilotlabError(f"{path}: tensor {tensor.name!r} keeps its data in {location!r}, which is not "
                                f"a file beside it (looked for {folder / location}); copy it there")
        files[location] = target
    return files


def planned_data_files(path: Path) -> dict[str, Path]:
    """The external data files of the ONNX file `path`, for planning: none if it cannot be read as
    ONNX (the train job says why when it runs)."""
    try:
        model = load_without_data(path)
    except PilotlabError:
        return {}
    return external_data_files(model, path, "the model file's folder")
