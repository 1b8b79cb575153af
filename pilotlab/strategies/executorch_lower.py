"""Lowering a network to an ExecuTorch .pte with the XNNPACK backend (torch and executorch are
imported here, which only the executorch_xnnpack handlers import)."""
from __future__ import annotations

import warnings

import torch
from torch import nn

from pilotlab.strategies.artifact import example_batch
from pilotlab.strategies.fold import fold_input_norm
from pilotlab.strategies.registry import StrategySource


def save_pte(model: nn.Module, source: StrategySource, max_batch: int, quantizer: dict | None) -> None:
    """Export `model` (int8 when `quantizer` = {"per_channel", "calibration_frames"}), lower every
    supported op to XNNPACK and write source.out/model.pte plus artifact.json."""
    from executorch.backends.xnnpack.partition.xnnpack_partitioner import XnnpackPartitioner
    from executorch.exir import to_edge_transform_and_lower
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        program = _export(fold_input_norm(model.eval()), source.input_shape, max_batch)
        if quantizer:
            program = _export(_quantized(program, source, **quantizer), source.input_shape, max_batch)
        lowered = to_edge_transform_and_lower(program, partitioner=[XnnpackPartitioner()])
        outside = _ops_outside_xnnpack(lowered)
        program = lowered.to_executorch()
        (source.out / "model.pte").write_bytes(program.buffer)
    extra = {"backend": "XNNPACK", "max_batch": _planned_batch(program), "ops_outside_xnnpack": outside}
    if quantizer:
        extra |= {"quantizer": "executorch XNNPACKQuantizer (symmetric)",
                  "weights": "int8 per channel" if quantizer["per_channel"] else "int8 per tensor",
                  "activations": "int8 per tensor"}
    source.write(source.meta(format="executorch-pte", file="model.pte", runtime="executorch",
                             dtype="int8" if quantizer else "float32", extra=extra))


def _export(model: nn.Module, input_shape: tuple, max_batch: int) -> torch.export.ExportedProgram:
    # a batch-2 example: torch.export specialises a dimension of size 1
    batch = torch.export.Dim("batch", min=1, max=max_batch)
    return torch.export.export(model, (example_batch(input_shape),), dynamic_shapes=({0: batch},))


def _quantized(program: torch.export.ExportedProgram, source: StrategySource, *, per_channel: bool,
               calibration_frames: int) -> nn.Module:
    from executorch.backends.xnnpack.quantizer.xnnpack_quantizer import (
        XNNPACKQuantizer, get_symmetric_quantization_config)
    from torchao.quantization.pt2e.quantize_pt2e import convert_pt2e, prepare_pt2e
    quantizer = XNNPACKQuantizer().set_global(get_symmetric_quantization_config(is_per_channel=per_channel))
    prepared = prepare_pt2e(program.module(), quantizer)
    with torch.no_grad():
        for batch in source.calibration_batches(calibration_frames):
            prepared(batch)
    return convert_pt2e(prepared)


def _planned_batch(program) -> int:
    """The largest batch the program's memory plan holds. ExecuTorch 1.5 plans PilotNet's input for
    15 images whatever the export's upper bound (its shape evaluation bounds the convolutions'
    symbolic sizes on its own), so the predictor reads the real figure from here and slices."""
    plan = program.executorch_program.execution_plan[0]
    return int(plan.values[plan.inputs[0]].val.sizes[0])


def _ops_outside_xnnpack(lowered) -> list[str]:
    """The operators left to ExecuTorch's portable kernels (not taken by XNNPACK): a slow path."""
    graph = lowered.exported_program().graph
    return sorted({str(node.target).split(".")[-2] if "." in str(node.target) else str(node.target)
                   for node in graph.nodes if node.op == "call_function"
                   and "executorch_call_delegate" not in str(node.target) and "getitem" not in str(node.target)})
