"""How fast a training step runs in the memory layouts `fit` could use, from one run, interleaved:
`python -m pytest -m benchmark -s tests/pilotlab/test_training_benchmark.py`.

PilotNet, a batch of 64 (the study's), Adam, on 1 thread (a fine-tune on its worker's share) and on
every core (the training, which runs alone). Prints the median step of each layout and its ratio to
the one `fit` uses (the input NCHW-contiguous, the weights channels-last: pilotlab/training.py):
- "NHWC view": the input as the permuted view of the NHWC frames, what `fit` was fed before, whose
  channels-last strides reach the input BatchNorm (10× slower there on 2 threads, torch 2.13);
- "NCHW": input and weights in the standard layout;
- "bf16": fit's layout in bf16 mixed precision (autocast forward pass: what precision auto trains in where
  the CPU has AVX512-BF16 or AMX; elsewhere torch emulates bf16 and it is slower, said in the print).
Never asserts a timing (the machine is shared); asserts only that every layout computes the same first
loss, to float rounding (BatchNorm and convolutions sum in another order: 5e-4 apart seen; bf16 rounds
the forward pass to 8 significant bits: 2e-2 allowed).
"""
from __future__ import annotations

import os
import statistics
import time
from contextlib import nullcontext

import numpy as np
import pytest
import torch

from pilotlab.cpuinfo import native_cpu_dtype
from pilotlab.models.configs import PilotNetConfig
from pilotlab.models.pilotnet import PilotNet
from pilotlab.training import _channels_last_convolutions

pytestmark = pytest.mark.benchmark
LAYOUTS = ("fit's (NCHW input, channels-last weights)", "NHWC view", "NCHW", "bf16")


def frames(batch: int) -> torch.Tensor:
    """A batch as FrameSet.inputs builds it from uint8 NHWC frames, before the .contiguous() it now ends with."""
    nhwc = np.random.default_rng(0).integers(0, 256, (batch, 66, 200, 3), dtype=np.uint8)
    return torch.from_numpy(nhwc).permute(0, 3, 1, 2).float().div_(255.0)


def setup(layout: str, batch: int) -> tuple[torch.nn.Module, torch.Tensor]:
    torch.manual_seed(0)
    model, inputs = PilotNet(PilotNetConfig()), frames(batch)
    return model, inputs if layout == "NHWC view" else inputs.contiguous()


def step_seconds(layout: str, batch: int, steps: int) -> tuple[list[float], float]:
    """Each timed step's seconds (after two untimed ones) and the first step's loss."""
    model, inputs = setup(layout, batch)
    with _channels_last_convolutions(model, inputs[:2]) if layout in (LAYOUTS[0], "bf16") else nullcontext():
        return _steps(model, inputs, steps, bf16=layout == "bf16")


def _steps(model: torch.nn.Module, inputs: torch.Tensor, steps: int, bf16: bool) -> tuple[list[float], float]:
    targets = torch.rand(len(inputs), 2, generator=torch.Generator().manual_seed(1))
    optimizer = torch.optim.Adam(model.parameters(), lr=1e-3)
    times, first_loss = [], None
    for step in range(steps + 2):
        started = time.perf_counter()
        optimizer.zero_grad()
        with torch.autocast("cpu", dtype=torch.bfloat16, enabled=bf16):
            outputs = model(inputs)
        loss = torch.nn.functional.mse_loss(outputs.float(), targets)
        loss.backward()
        optimizer.step()
        first_loss = loss.item() if first_loss is None else first_loss
        if step >= 2:
            times.append(time.perf_counter() - started)
    return times, first_loss


@pytest.mark.parametrize("threads", [1, os.cpu_count() or 1])
def test_training_step_per_memory_layout(threads):
    before = torch.get_num_threads()
    torch.set_num_threads(threads)
    try:
        times = {layout: [] for layout in LAYOUTS}
        losses = {}
        for _ in range(3):                  # in turn, so a change of the host's speed touches all alike
            for layout in LAYOUTS:
                seconds, losses[layout] = step_seconds(layout, 64, 6)
                times[layout] += seconds
    finally:
        torch.set_num_threads(before)
    medians = {layout: statistics.median(values) for layout, values in times.items()}
    print(f"\nPilotNet training step, batch 64, {threads} thread(s), median of {len(times[LAYOUTS[0]])} steps "
          f"(load average {os.getloadavg()[0]:.1f} on {os.cpu_count()} cores; bf16 "
          f"{'native' if native_cpu_dtype('bfloat16') else 'emulated: precision auto trains fp32 here'}):")
    for layout in LAYOUTS:
        print(f"  {layout:<42} {medians[layout] * 1e3:7.1f} ms   {medians[layout] / medians[LAYOUTS[0]]:.2f}x fit's")
    reference = losses[LAYOUTS[0]]
    assert all(abs(loss - reference) <= (2e-2 if layout == "bf16" else 1e-2) * abs(reference)
               for layout, loss in losses.items()), losses
