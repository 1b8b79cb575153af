"""The report's plots (PNG + SVG), drawn with matplotlib's object API on the Agg canvas.

Each function draws one figure from a `ReportData` and returns it, or None when there is nothing to
draw (no measured points); `save_plots` writes whatever exists. Colour means strategy and marker
shape means model everywhere, so a strategy looks the same in every plot.
"""
from __future__ import annotations

import math
import warnings
from collections.abc import Callable
from pathlib import Path

import matplotlib
from matplotlib.figure import Figure
from matplotlib.lines import Line2D

from matplotlib.patches import Patch

from pilotlab.report.data import TIMED, ReportData, ReportRow, timing_issue
from pilotlab.report.worlds import WorldCell, ratio, training_cell, world_cells

MARKERS = "osD^vP*h"
STYLE = {"font.size": 10, "axes.titlesize": 11, "axes.spines.top": False, "axes.spines.right": False,
         "svg.hashsalt": "pilotlab", "svg.fonttype": "none", "figure.dpi": 110}


def save_plots(data: ReportData, folder: Path) -> dict[str, tuple[Path, Path]]:
    """Draw every plot that has data; write `<name>.png` and `<name>.svg`; return name -> (png, svg)."""
    folder.mkdir(parents=True, exist_ok=True)
    written = {}
    with matplotlib.rc_context(STYLE), warnings.catch_warnings():
        # a name in a script the font lacks (モデル) is drawn as boxes; the tables beside each plot spell it
        warnings.filterwarnings("ignore", message=r"Glyph \d+ .*missing from", category=UserWarning)
        for name, draw in PLOTS.items():
            figure = draw(data)
            if figure is None:
                continue
            png, svg = folder / f"{name}.png", folder / f"{name}.svg"
            figure.savefig(png, dpi=110, metadata={"Software": None})
            figure.savefig(svg, metadata={"Date": None, "Creator": None})
            written[name] = (png, svg)
    return written


def strategy_colours(data: ReportData) -> dict[str, tuple]:
    cmap = matplotlib.colormaps["tab10" if len(data.strategies()) <= 10 else "tab20"]
    return {strategy: cmap(i % cmap.N) for i, strategy in enumerate(data.strategies())}


def model_markers(data: ReportData) -> dict[str, str]:
    return {model: MARKERS[i % len(MARKERS)] for i, model in enumerate(data.models())}


def pareto_front(points: list[tuple[float, float]]) -> list[tuple[float, float]]:
    """The points no other point beats on both axes (lower is better on both), by increasing x."""
    front: list[tuple[float, float]] = []
    for x, y in sorted(points):
        if not front or y < front[-1][1]:
            front.append((x, y))
    return front


def _grid(count: int, width: float = 5.2, height: float = 4.0, columns: int = 3) -> tuple[Figure, list]:
    ncols = min(count, columns)
    nrows = math.ceil(count / ncols)
    # at least 8 in wide: the legend sits outside on the right and the title spans the whole figure
    figure = Figure(figsize=(max(width * ncols, 8.0), height * nrows), layout="constrained")
    axes = figure.subplots(nrows, ncols, squeeze=False).ravel().tolist()
    for unused in axes[count:]:
        unused.set_visible(False)
    return figure, axes[:count]


def _legend_and_title(figure: Figure, handles: list[Line2D], title: str) -> None:
    """The legend outside on the right, from the top; the title therefore starts at the left edge
    (centred, a long title ran into the legend's first entries)."""
    figure.legend(handles=handles, loc="outside right upper", frameon=False)
    figure.suptitle(title, x=0.01, ha="left")


def _identity_handles(data: ReportData, rows: list[ReportRow]) -> list[Line2D]:
    colours, markers = strategy_colours(data), model_markers(data)
    shown = dict.fromkeys(r.strategy for r in rows)
    handles = [Line2D([], [], ls="", marker="o", color=colours[s], markersize=8, label=s) for s in shown]
    models = list(dict.fromkeys(r.model for r in rows))
    if len(models) > 1:   # one model (the references are not plotted here): its marker says nothing
        handles += [Line2D([], [], ls="", marker=markers[m], color="0.4", markersize=8, label=m) for m in models]
    return handles


def draw_pareto(data: ReportData) -> Figure | None:
    rows = [r for r in data.of_kind("offline") if r.get("latency_ms") is not None and r.get("mse") is not None]
    if not rows:
        return None
    hardware = list(dict.fromkeys(r.hardware for r in rows))
    figure, axes = _grid(len(hardware))
    biggest = max((r.get("size_mb") or 0 for r in rows), default=0) or 1.0
    area = lambda size: 40 + 700 * size / biggest  # noqa: E731  (marker area ∝ model size)
    colours, markers = strategy_colours(data), model_markers(data)
    fronts: list[int] = []   # the points of each front drawn
    for ax, target in zip(axes, hardware):
        here = [r for r in rows if r.hardware == target]
        for r in here:
            size, unstable = r.get("size_mb"), r.unstable_reason("latency_ms") is not None
            latency, low, high = r.get("latency_ms"), r.get("latency_p10_ms"), r.get("latency_p90_ms")
            if low is not None and high is not None:    # the 10th–90th percentile of the latency
                ax.errorbar(latency, r.get("mse"), xerr=[[latency - low], [high - latency]], fmt="none",
                            ecolor="0.4", elinewidth=1, capsize=3, zorder=2)
            ax.scatter(r.get("latency_ms"), r.get("mse"), s=area(size or 0), marker=markers[r.model],
                       color="none" if unstable else colours[r.strategy], alpha=0.75,
                       edgecolors=colours[r.strategy] if unstable else "black", linewidths=1.5 if unstable else 0.6,
                       zorder=3)
        # the front of the trusted timings only; one method best on both counts is the whole front: a
        # square round it, as a lone step draws nothing (a ring would read as the unstable marker)
        front = pareto_front([(r.get("latency_ms"), r.get("mse")) for r in here if not r.unstable_reason("latency_ms")])
        if front:
            ax.plot(*zip(*front), drawstyle="steps-post", color="0.35", ls="--", lw=1.2, zorder=2,
                    marker="s" if len(front) == 1 else None, markersize=22, markerfacecolor="none")
            fronts.append(len(front))
        ax.set(title=target, xlabel="Inference time, batch 1 (ms)", ylabel="MSE (normalised v, w)")
        ax.margins(0.15)
        ax.set_xlim(left=max(0.0, ax.get_xlim()[0]))   # no negative milliseconds
        ax.grid(alpha=0.3)
    sizes = sorted({round(r.get("size_mb"), 2) for r in rows if r.get("size_mb")})
    shown = dict.fromkeys(sizes[i] for i in (0, len(sizes) // 2, -1)) if sizes else {}     # smallest, middle, largest
    size_handles = [Line2D([], [], ls="", marker="o", markersize=math.sqrt(area(s)), color="0.75",
                           markeredgecolor="black", label=f"{s:g} MB") for s in shown]
    front_handles = [Line2D([], [], color="0.35", ls="--", marker="s" if 1 in fronts else None, markersize=8,
                            markerfacecolor="none", label="Pareto front (stable timings)")] if fronts else []
    if any(r.unstable_reason("latency_ms") for r in rows):
        size_handles.append(Line2D([], [], ls="", marker="o", markersize=8, markerfacecolor="none",
                                   markeredgecolor="0.3", label="⚠ unstable timing"))
    _legend_and_title(figure, _identity_handles(data, rows) + front_handles + size_handles,
                      "Latency vs MSE (lower left is better; marker area ∝ model size)")
    return figure


def _ratio_bars(ax, data: ReportData, groups: list[str], metric: str, title: str) -> None:
    """Horizontal bars of baseline/value, one line per model and strategy, one bar per hardware."""
    offline = data.of_kind("offline")
    categories = sorted(dict.fromkeys((r.model, r.strategy) for r in offline),
                        key=lambda c: (data.models().index(c[0]), data.strategies().index(c[1])))
    height = 0.8 / max(1, len(groups))
    for g, group in enumerate(groups):
        for y, (model, strategy) in enumerate(categories):
            row = next((r for r in offline if (r.model, r.strategy, r.hardware) == (model, strategy, group)), None)
            base = next((r for r in offline if (r.model, r.strategy, r.hardware) == (model, data.baseline, group)
                         and r.status == "ok"), None)
            if row is not None:
                _ratio_bar(ax, row, base, metric, y - 0.4 + height * (g + 0.5), height, g)
    ax.axvline(1.0, color="0.3", lw=1)
    labels = [s if len(data.models()) <= 1 else f"{m} · {s}" for m, s in categories]
    ax.set_yticks(range(len(categories)), labels)
    ax.set(title=title, xlabel="× baseline (above 1× is better)")
    ax.set_xlim(0, max(1.5, ax.get_xlim()[1] * 1.12))   # room for the value labels
    ax.grid(axis="x", alpha=0.3)


def _ratio_bar(ax, row: ReportRow, base: ReportRow | None, metric: str, position: float, height: float,
               index: int) -> None:
    if row.status != "ok" or row.get(metric) is None or base is None or base.get(metric) is None:
        label = {"not_applicable": "not applicable", "failed": "failed",
                 "not_run": "not run yet"}.get(row.status, "not measured")
        ax.text(0.05, position, label, ha="left", va="center", fontsize=8, color="0.35", style="italic")
        return
    if metric in TIMED and timing_issue([base, row], metric) is not None:    # no bar drawn from it
        ax.text(0.05, position, "⚠ unstable timing", ha="left", va="center", fontsize=8, color="0.35", style="italic")
        return
    colour = matplotlib.colormaps["Set2"](index % 8)
    bar = ax.barh(position, base.get(metric) / row.get(metric), height, color=colour, edgecolor="black", lw=0.5)
    ax.bar_label(bar, fmt="%.2f×", fontsize=8, padding=3)


def draw_ratios(data: ReportData) -> Figure | None:
    offline = data.of_kind("offline")
    if not any(r.strategy == data.baseline and r.status == "ok" for r in offline):
        return None
    hardware = list(dict.fromkeys(r.hardware for r in offline))
    lines = len(dict.fromkeys((r.model, r.strategy) for r in offline))
    figure = Figure(figsize=(11, 1.2 + 0.32 * lines * max(1, len(hardware) * 0.7)), layout="constrained")
    size_ax, speed_ax = figure.subplots(1, 2, sharey=True)
    _ratio_bars(size_ax, data, hardware[:1], "size_mb", "Size reduction (baseline size / size)")
    _ratio_bars(speed_ax, data, hardware, "latency_ms", "Speed-up, batch 1 (baseline latency / latency)")
    size_ax.invert_yaxis()                         # recipe order, top to bottom (the y axis is shared)
    if len(hardware) > 1:
        colours = matplotlib.colormaps["Set2"]
        speed_ax.legend(handles=[Line2D([], [], lw=6, color=colours(i % 8), label=h) for i, h in enumerate(hardware)],
                        frameon=False, fontsize=8, loc="lower right")
    figure.suptitle(f"Strategies against {data.baseline}")
    return figure


def _place_panels(rows: list) -> tuple[Figure, list]:
    """A panel per (hardware, circuit and direction) of the rows: the figure and, per panel,
    (axes, hardware, place, the rows driven there)."""
    places = list(dict.fromkeys((r.hardware, r.place) for r in rows))
    figure, axes = _grid(len(places))
    return figure, [(ax, target, place, [r for r in rows if (r.hardware, r.place) == (target, place)])
                    for ax, (target, place) in zip(axes, places)]


def draw_closed_loop(data: ReportData) -> Figure | None:
    rows = [r for r in data.of_kind("online")
            if r.get("average_speed") is not None and r.get("position_deviation_mae_m") is not None]
    if not rows:
        return None
    figure, panels = _place_panels(rows)
    colours, markers = strategy_colours(data), model_markers(data)
    for ax, target, place, here in panels:
        for r in here:
            lost = r.get("lap_completed") is False
            ax.scatter(r.get("position_deviation_mae_m"), r.get("average_speed"), s=90, zorder=3,
                       marker="X" if lost else markers[r.model], color=colours[r.strategy],
                       edgecolors="crimson" if lost else "black", linewidths=1.2 if lost else 0.6)
        ax.set(title=f"{place} · {target}", xlabel="Position deviation MAE (m), lower is better",
               ylabel="Average speed (m/s), higher is better")
        ax.margins(0.2)
        ax.grid(alpha=0.3)
    _legend_and_title(figure, _identity_handles(data, rows) + [_lost_lap_handle()],
                      "Closed loop: speed vs deviation from the red line (upper left is better)")
    return figure


def _lost_lap_handle() -> Line2D:
    """The legend's entry for the ✗ that marks a lap not completed (laps and tolerance plots)."""
    return Line2D([], [], ls="", marker="X", color="0.6", markeredgecolor="crimson", markersize=9,
                  label="lap not completed")


def draw_latency_tolerance(data: ReportData) -> Figure | None:
    """Deviation against injected latency, one line per strategy and panel per (hardware, circuit):
    the laps of each cell's tolerance search; lost laps marked ✗ (their deviation until they left)."""
    rows = [r for r in data.of_kind("online") if r.status == "ok" and r.tolerance]
    if not rows:
        return None
    figure, panels = _place_panels(rows)
    colours, markers = strategy_colours(data), model_markers(data)
    for ax, target, place, here in panels:
        for r in here:
            points = [p for p in r.tolerance if p.position_deviation_mae_m is not None]
            done = [p for p in points if p.lap_completed]
            ax.plot([p.injected_ms for p in done], [p.position_deviation_mae_m for p in done],
                    color=colours[r.strategy], marker=markers[r.model], markersize=5, lw=1.4)
            lost = [p for p in points if not p.lap_completed]
            ax.scatter([p.injected_ms for p in lost], [p.position_deviation_mae_m for p in lost], marker="X", s=70,
                       color=colours[r.strategy], edgecolors="crimson", linewidths=1.0, zorder=3)
        ax.set(title=f"{place} · {target}", xlabel="Injected latency (ms)",
               ylabel="Position deviation MAE (m), lower is better")
        if ax.get_xlim()[1] - ax.get_xlim()[0] < 20:   # one latency alone (a lap lost at 0): ±0.04 ms read oddly
            ax.set_xlim(-10, 100)
        ax.grid(alpha=0.3)
    _legend_and_title(figure, _identity_handles(data, rows) + [_lost_lap_handle()],
                      "Latency tolerance: deviation as latency is added to each brain's own")
    return figure


def draw_training(data: ReportData) -> Figure | None:
    histories = {model: points for model, points in data.histories.items() if points}
    if not histories:
        return None
    figure, axes = _grid(len(histories), width=5.0, height=3.6)
    for ax, (model, points) in zip(axes, histories.items()):
        epochs = [p.epoch for p in points]
        ax.plot(epochs, [p.train_loss for p in points], marker="o", ms=3, label="train loss")
        validated = [p for p in points if p.val_loss is not None]
        if validated:
            ax.plot([p.epoch for p in validated], [p.val_loss for p in validated], marker="s", ms=3, ls="--",
                    label="validation loss")
        losses = [p.train_loss for p in points] + [p.val_loss for p in validated]
        if min(losses) > 0 and max(losses) / min(losses) > 20:
            ax.set_yscale("log")
        ax.set(title=model + _precision_note(points), xlabel="epoch", ylabel="MSE loss (normalised)")
        ax.grid(alpha=0.3)
        ax.legend(frameon=False)
    figure.suptitle("Training curves")
    return figure


def _precision_note(points) -> str:
    """The title's note on how the epochs were trained (models.<name>.precision): " (bf16 mixed precision)"."""
    precisions = sorted({p.precision for p in points if p.precision})
    named = ("bf16 mixed precision" if p == "bf16" else p for p in precisions)
    return f" ({', '.join(named)})" if precisions else ""


def draw_world_shift(data: ReportData):
    """Per model: for each world (the training world first) and strategy, a bar of the offline MSE over
    the training world's (left) and of BM's deviation over the training world's (right); a hatched bar
    is a lap that was not completed. None when no world shifted, or none was evaluated in its training world
    (nothing to divide by: it drew two empty panels)."""
    cells = world_cells(data)
    if not any(not c.training for c in cells) or not any(c.training for c in cells):
        return None
    models = [m for m in data.models() if any(c.model == m for c in cells)]
    colours = strategy_colours(data)
    figure = Figure(figsize=(11.0, 3.6 * len(models)), layout="constrained")
    axes = figure.subplots(len(models), 2, squeeze=False)
    for (left, right), model in zip(axes, models):
        chosen = [c for c in cells if c.model == model]
        worlds = sorted({c.world for c in chosen}, key=lambda w: (not any(c.training and c.world == w for c in chosen), w))
        strategies = [s for s in data.strategies() if any(c.strategy == s for c in chosen)]
        for ax, metric, label in ((left, "mse", "offline MSE × training world"),
                                  (right, DEVIATION, "BM deviation × training world")):
            _shift_bars(ax, chosen, cells, worlds, strategies, colours, metric)
            ax.set(ylabel=label, title=f"{model}: {label.split(' ×')[0]}")
            heights = [patch.get_height() for patch in ax.patches]
            if heights and max(heights) > 20 * max(min(heights), 1e-9):
                ax.set_yscale("log")     # BM's deviation grows as 1000^d: a lost lap is orders above
            ax.axhline(1.0, color="0.5", lw=0.8, ls="--")
    shown = [s for s in data.strategies() if any(c.strategy == s for c in cells)]   # the reference rows are not
    handles = [Patch(color=colours[s], label=s) for s in shown]
    handles.append(Patch(facecolor="white", edgecolor="0.3", hatch="///", label="lap not completed"))
    handles.append(Line2D([], [], marker="x", ls="", ms=9, mew=2, color="0.3",
                          label="a lap lost: no deviation ratio (at the top)"))
    figure.legend(handles=handles, loc="outside right upper", frameon=False)
    figure.suptitle("World shift: each world against the training world (above 1× is worse)", x=0.01, ha="left")
    return figure


DEVIATION = "bm_position_deviation_mae"
LOST_AT = 0.95   # where a lost lap's cross sits, as a fraction of the panel's height


def _shift_bars(ax, chosen: list[WorldCell], cells: list[WorldCell], worlds, strategies, colours, metric) -> None:
    width = 0.8 / max(len(strategies), 1)
    for i, strategy in enumerate(strategies):
        for j, world in enumerate(worlds):
            cell = next((c for c in chosen if c.strategy == strategy and c.world == world), None)
            base = training_cell(cells, cell) if cell is not None else None
            value = ratio(cell.metric(metric), base.metric(metric)) if cell and base else None
            if value is None:
                continue
            lost = cell.metric("lap_completed") is False
            x = j + (i - (len(strategies) - 1) / 2) * width
            if metric == DEVIATION and not cell.training and (lost or base.metric("lap_completed") is False):
                # as the table: a lost lap's deviation grows without bound, a ratio to it says nothing; the
                # cross sits at the top of the panel (at 1.0 it read "as in the training world")
                ax.plot(x, LOST_AT, marker="x", ls="", ms=9, mew=2, color=colours[strategy],
                        transform=ax.get_xaxis_transform(), clip_on=False)
                continue
            ax.bar(x, value, width, color=colours[strategy],
                   hatch="///" if lost else None, edgecolor="0.3" if lost else colours[strategy])
    ax.set_xticks(range(len(worlds)), [w.replace("simple_circuit_", "").replace("_", " ") for w in worlds],
                  rotation=20, ha="right")


PLOTS: dict[str, Callable[[ReportData], Figure | None]] = {
    "pareto": draw_pareto,
    "ratios": draw_ratios,
    "closed_loop": draw_closed_loop,
    "latency_tolerance": draw_latency_tolerance,
    "training": draw_training,
    "world_shift": lambda data: draw_world_shift(data),
}
CAPTIONS = {
    "pareto": "Latency vs MSE per hardware: the dashed line is the Pareto front, marker area is the model size, "
              "whiskers the latency's 10th–90th percentile; a hollow marker is an unstable timing.",
    "ratios": "Size reduction and speed-up of each strategy against the baseline (no bar where a timing was "
              "unstable or the strategy not applicable).",
    "closed_loop": "Closed-loop laps: average speed against position deviation; a cross marks a lost lap.",
    "latency_tolerance": "Latency tolerance: each lap cell driven again with more latency injected; position "
                         "deviation against the injected latency, a cross marks a lost lap; cells whose "
                         "tolerance was not searched (online.tolerance.only) are not drawn.",
    "training": "Training and validation loss per epoch for each model.",
    "world_shift": "World shift: each strategy's offline MSE and BehaviorMetrics deviation in each world over its "
                   "value in the training world; a hatched bar is a lap that was not completed; a cross at the top "
                   "of the deviation panel, a lost lap (a ratio to its deviation says nothing)."
}

