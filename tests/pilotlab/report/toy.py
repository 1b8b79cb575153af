"""Toy report data shaped like the 2022 study's PyTorch results, with every awkward case in it.

Two hardware targets, two circuits, a not-applicable strategy, a failed cell, a lost lap, an
unmeasured metric, and real trajectory PNGs (a path drawn over a red line, as the simulator draws).
"""
from __future__ import annotations

import math
from pathlib import Path

from matplotlib.figure import Figure

# strategy: (size MB, MSE, latency ms on cpu1, throughput images/s)
OFFLINE = {
    "baseline": (6.12, 0.0788, 2.18, 910.0),
    "dynamic_quant": (1.95, 0.0784, 3.17, 640.0),
    "static_quant": (1.61, 0.0788, 2.66, 1210.0),
    "qat": (1.61, 0.0708, 2.79, 1150.0),
    "local_prune": (6.12, 0.0729, 2.09, 930.0),
    "global_prune": (6.12, 0.0708, 2.15, 925.0),
    "prune_quant": (1.61, 0.0672, 2.66, 1190.0),
}
# strategy: (lap completed, percentage, lap seconds, average speed, deviation MAE, brain Hz, inference ms, RTF)
ONLINE = {
    "baseline": (True, 100.0, 55.2, 8.39, 0.41, 20.0, 2.3, 0.95),
    "dynamic_quant": (True, 100.0, 54.3, 8.53, 0.37, 20.0, 3.2, 0.94),
    "local_prune": (False, 63.0, None, 7.74, 1.42, 20.0, 2.1, 0.96),
    "prune_quant": (True, 100.0, 52.4, 8.84, 0.26, 20.0, 2.7, 0.95),
}


def draw_trajectory(path: Path, wobble: float) -> Path:
    """A small real PNG: the car's path (blue) over the red centre line, as the simulator side draws."""
    figure = Figure(figsize=(3.2, 2.4), dpi=60, layout="constrained")
    ax = figure.subplots()
    angles = [i / 100 * 2 * math.pi for i in range(101)]
    ax.plot([30 * math.cos(a) for a in angles], [18 * math.sin(a) for a in angles], color="red", lw=2)
    ax.plot([(30 + wobble * math.sin(7 * a)) * math.cos(a) for a in angles],
            [(18 + wobble * math.sin(5 * a)) * math.sin(a) for a in angles], color="tab:blue", lw=1)
    ax.set_aspect("equal")
    ax.set_axis_off()
    figure.savefig(path)
    return path


def offline_rows(hardware: str, slowdown: float = 1.0) -> list[dict]:
    rows = []
    for strategy, (size, mse, latency, throughput) in OFFLINE.items():
        rows.append({"model": "pilotnet", "strategy": strategy, "hardware": hardware, "kind": "offline",
                     "test_set": "simple_circuit+montreal", "job_keys": {"offline": f"off-{hardware}-{strategy}"},
                     "size_mb": size, "mse": mse, "latency_ms": latency * slowdown,
                     "throughput_ips": throughput / slowdown, "test_frames": 480, "threads": 1})
    return rows


def online_rows(tmp_path: Path, circuit: str) -> list[dict]:
    rows = []
    for i, (strategy, values) in enumerate(ONLINE.items()):
        done, share, seconds, speed, deviation, hz, inference, rtf = values
        picture = draw_trajectory(tmp_path / f"{circuit}-{strategy}.png", wobble=deviation * 3)
        rows.append({"model": "pilotnet", "strategy": strategy, "hardware": "cpu1", "kind": "online",
                     "circuit": circuit, "direction": "cw", "trajectory": str(picture),
                     "job_keys": {"online": f"on-{circuit}-{i}"},
                     "metrics": {"lap_completed": done, "percentage_completed": share, "lap_seconds": seconds,
                                 "average_speed": speed, "position_deviation_mae_m": deviation,
                                 "brain_frequency_sim_hz": hz, "mean_inference_ms": inference,
                                 "real_time_factor": rtf}})
    return rows


def study_dict(tmp_path: Path, **overrides) -> dict:
    rows = offline_rows("cpu1") + offline_rows("cpu4", slowdown=0.45)
    rows[9]["status"], rows[9]["reason"] = "not_applicable", "static quantization kernels need 1 thread here"
    rows[10] = {**rows[10], "status": "failed", "reason": "RuntimeError: QAT fine-tuning diverged (loss nan)"}
    del rows[3]["throughput_ips"]                                  # qat on cpu1: throughput not measured
    rows += online_rows(tmp_path, "simple_circuit") + online_rows(tmp_path, "montreal")
    rows.append({"model": "pilotnet", "strategy": "static_quant", "hardware": "cpu1", "kind": "online",
                 "circuit": "montreal", "direction": "cw", "status": "failed",
                 "reason": "simulator crashed: pybullet lost its connection"})
    data = {
        "recipe_name": "study-2022",
        "description": "Re-creates the 2022 PilotNet optimisation study (PyTorch set) on two CPU profiles.",
        "recipe_text": "name: study-2022\nmatrix:\n  strategy: [baseline, dynamic_quant]\n",
        "versions": {"pilotlab": "0.1.0", "torch": "2.13.0", "onnxruntime": "1.22.0"},
        "host": {"cpu": "AMD EPYC 7B13", "cores": 2, "gpu": None},
        "date": "2025-06-01T10:30:00",
        "rows": rows,
        "histories": {"pilotnet": [{"epoch": e, "train_loss": 0.2 / e, "val_loss": 0.25 / e ** 0.8}
                                   for e in range(1, 11)]},
    }
    return {**data, **overrides}


def offline_row(strategy: str = "baseline", hardware: str = "cpu1", **fields) -> dict:
    return {"model": "pilotnet", "strategy": strategy, "hardware": hardware, "kind": "offline",
            "test_set": "simple_circuit", **fields}


def small_dict(rows: list[dict], **fields) -> dict:
    return {"recipe_name": "small", "date": "2025-06-01T10:30:00", "rows": rows, **fields}


def online_row(strategy: str = "baseline", runs: int = 1, **metrics) -> dict:
    """An online row as `report.recipe` builds it from an online job's result; with `runs` > 1, the
    spread of a lap repeated from `runs` start points (the job gives a spread for one run too)."""
    spread = {"lap_completed": {"completed": runs if metrics.get("lap_completed") else runs - 1, "runs": runs}}
    for name, value in metrics.items():
        if name != "lap_completed":
            spread[name] = {"std": 0.0, "min": value, "max": value, "runs": runs}
    return {"model": "pilotnet", "strategy": strategy, "hardware": "cpu1", "kind": "online",
            "circuit": "simple_circuit", "direction": "cw", **metrics, "spread": spread}


def with_spread(row: dict, **spreads: tuple[float, float, float]) -> dict:
    """`row` with the given metrics' spread set to (std, min, max)."""
    spread = dict(row["spread"])
    for name, (std, low, high) in spreads.items():
        spread[name] = {**spread[name], "std": std, "min": low, "max": high}
    return {**row, "spread": spread}


def repeated_rows() -> list[dict]:
    """Three laps from three start points (all completed; one of three lost) and a single lap."""
    baseline = with_spread(online_row("baseline", runs=3, lap_completed=True, percentage_completed=100.0,
                                      lap_seconds=47.83, average_speed=8.953, position_deviation_mae_m=0.2134),
                           lap_seconds=(0.41, 47.4, 48.3), average_speed=(0.123, 8.81, 9.05),
                           position_deviation_mae_m=(0.0004, 0.213, 0.2139))
    lost = with_spread(online_row("qat", runs=3, lap_completed=False, percentage_completed=87.2, lap_seconds=49.1,
                                  average_speed=8.41, position_deviation_mae_m=0.51),
                       percentage_completed=(22.2, 61.6, 100.0), average_speed=(0.3, 8.1, 8.7))
    lost["spread"]["lap_seconds"] = {"std": 0.2, "min": 48.96, "max": 49.24, "runs": 2}   # the completed laps
    single = online_row("local_prune", lap_completed=True, percentage_completed=100.0, lap_seconds=47.83,
                        average_speed=8.953, position_deviation_mae_m=0.2134)
    return [baseline, lost, single]
