"""Saving a network as a model file of an artifact: ONNX (the torch.export-based exporter) and
frozen TorchScript, with the example batch both trace with. Strategy handlers import this module
(torch at its top); artifact.json itself is pilotlab.strategies.artifact's."""
from __future__ import annotations

import contextlib
import functools
import io
import logging
import warnings
from collections.abc import Iterator
from pathlib import Path

import torch
from torch import nn

from pilotlab.strategies.artifact import INPUT_NAME, OUTPUT_NAME
from pilotlab.strategies.fold import fold_input_norm


def example_batch(input_shape: tuple, batch: int = 2, dtype: torch.dtype | None = None) -> torch.Tensor:
    # torch.export specialises a dimension of size 1, so a dynamic batch needs an example of 2.
    return torch.rand(batch, *input_shape[1:], generator=torch.Generator().manual_seed(0)).to(dtype or torch.float32)


def export_onnx(model: nn.Module, path: Path, input_shape: tuple) -> None:
    """ONNX via the torch.export-based exporter (the TorchScript one is deprecated in torch 2.x),
    with a dynamic batch dimension and the weights inside the one file (external_data=False). A user's
    ONNX graph is written as it is; a user's TorchScript model goes through the TorchScript exporter."""
    if hasattr(model, "onnx_bytes"):          # pilotlab.models.user.OnnxModel
        Path(path).write_bytes(model.onnx_bytes)
        return
    if isinstance(getattr(model, "module", None), torch.jit.ScriptModule):   # pilotlab.models.user.TorchScriptModel
        _export_torchscript_onnx(model.module, path, input_shape)
        return
    model = fold_input_norm(model)
    batch = torch.export.Dim("batch", min=1)
    with warnings.catch_warnings(), _quiet_onnx_exporter(), _torchlib_built_once():
        warnings.simplefilter("ignore")
        program = torch.onnx.export(model, (example_batch(input_shape),), dynamo=True,
                                    input_names=[INPUT_NAME], output_names=[OUTPUT_NAME],
                                    dynamic_shapes=({0: batch},), verbose=False)
    program.save(str(path), external_data=False)


@contextlib.contextmanager
def _torchlib_built_once() -> Iterator[None]:
    """torch.onnx rebuilds its table of ONNX decompositions on every export, parsing the source of each
    of ~500 onnxscript functions: ~1 s of a LiteRT strategy's ~6 s. The table depends on the installed
    torch and onnxscript and on which operators the process has registered (torchao's quantized ones
    appear when it is imported), so it is built once per set of operators and lent to each export
    (which only reads it). Where torch's private hooks are not there (another torch), the export
    builds its own table, as before."""
    try:
        from torch.onnx._internal.exporter import _registration
        own = _registration.ONNXRegistry.__dict__["from_torchlib"]
        operators = frozenset(torch._C._dispatch_get_all_op_names())
    except (ImportError, AttributeError, KeyError):
        yield
        return
    _registration.ONNXRegistry.from_torchlib = classmethod(
        lambda cls, *args, **kwargs: _built_torchlib(own.__get__(None, cls), operators, *args, **kwargs))
    try:
        yield
    finally:
        _registration.ONNXRegistry.from_torchlib = own


@functools.cache
def _built_torchlib(build, operators: frozenset, *args, **kwargs):
    return build(*args, **kwargs)


def _export_torchscript_onnx(module, path: Path, input_shape: tuple) -> None:
    with warnings.catch_warnings(), _quiet_onnx_exporter():
        warnings.simplefilter("ignore")
        torch.onnx.export(module, (example_batch(input_shape),), str(path), dynamo=False,
                          input_names=[INPUT_NAME], output_names=[OUTPUT_NAME],
                          dynamic_axes={INPUT_NAME: {0: "batch"}, OUTPUT_NAME: {0: "batch"}})


class _quiet_onnx_exporter:
    """The exporter prints progress lines and warnings about torchvision ops; silence them."""

    def __enter__(self):
        self._stack = contextlib.ExitStack()
        self._stack.enter_context(contextlib.redirect_stdout(io.StringIO()))
        self._logger = logging.getLogger("torch.onnx")
        self._level = self._logger.level
        self._logger.setLevel(logging.ERROR)
        return self

    def __exit__(self, *exc):
        self._logger.setLevel(self._level)
        self._stack.close()
        return False


def save_torchscript(model: nn.Module, path: Path, input_shape: tuple, dtype: torch.dtype | None = None,
                     device: str = "cpu") -> None:
    """Traced and frozen (weights folded in as constants, conv+relu fused): graph-level
    optimisation without Python at run time. `dtype` defaults to float32."""
    model = fold_input_norm(model.eval())
    with torch.no_grad(), warnings.catch_warnings():
        warnings.simplefilter("ignore")
        traced = torch.jit.trace(model, example_batch(input_shape, 1, dtype).to(device))
        frozen = torch.jit.freeze(traced)
    torch.jit.save(frozen, str(path))
