"""The world-shift section: how each strategy's network fares in BehaviorMetrics' world variants
against the world it was trained in (pilotlab.worlds; recipes/bm_worlds.yaml).

For every model × strategy × hardware and every world the recipe sweeps: the lap (completed or not),
BM's position deviation, the latency tolerance and the offline MSE on recordings made in that world,
each beside its value in the training world. The question it answers: does an optimized network lose
more than the baseline when the world shifts?
"""
from __future__ import annotations

from dataclasses import dataclass

from pilotlab.report.data import ReportData, ReportRow
from pilotlab.report.tables import MISSING, Cell, Table, TableRow, format_value, lap_cell, tolerance_cell

HEADERS = ("World", "Lap", "BM deviation MAE", "Latency tolerance (ms)", "Offline MSE", "MSE × training world",
           "BM deviation × training world")


@dataclass(frozen=True)
class WorldCell:
    """One model × strategy × hardware in one world: its lap (online) and offline rows."""
    model: str
    strategy: str
    hardware: str
    world: str
    lap: ReportRow | None
    offline: ReportRow | None
    training: bool                  # the world its training recordings were made in

    def metric(self, name: str):
        for row in (self.lap, self.offline):
            value = row.get(name) if row is not None else None
            if value is not None:
                return value
        return None


def world_cells(data: ReportData) -> list[WorldCell]:
    """Every (model, strategy, hardware, world) that has a lap or an offline row in a world."""
    found: dict[tuple, dict[str, ReportRow]] = {}
    for row in data.rows:
        if row.world is not None and row.model != "reference":
            key = (row.model, row.strategy, row.hardware, row.world)
            found.setdefault(key, {}).setdefault(row.kind, row)
    return [WorldCell(*key, rows.get("online"), rows.get("offline"), key[3] in data.training_worlds.get(key[0], ()))
            for key, rows in found.items()]


def training_cell(cells: list[WorldCell], cell: WorldCell) -> WorldCell | None:
    return next((c for c in cells if c.training and (c.model, c.strategy, c.hardware) ==
                 (cell.model, cell.strategy, cell.hardware)), None)


def ratio(value, reference) -> float | None:
    if value is None or reference is None or not reference:
        return None
    return float(value) / float(reference)


def _ratio_cell(value: float | None, training: bool) -> Cell:
    if training:
        return Cell("training world", 1.0, "the world the network was trained in")
    if value is None:
        return Cell(MISSING, None, "not measured here or in the training world", missing=True)
    return Cell(f"{value:.2f}×", value, "this world's value over the training world's (above 1× is worse)")


def _metric(cell: WorldCell, name: str) -> Cell:
    value = cell.metric(name)
    if value is None:
        return Cell(MISSING, None, "not measured", missing=True)
    return Cell(format_value(name, value), float(value), name)


def world_tables(data: ReportData) -> list[Table]:
    """One table per model × hardware: a row per strategy and world, the training world first."""
    cells = world_cells(data)
    if not any(not c.training for c in cells):
        return []
    strategies = data.strategies()
    tables = []
    for model in data.models():
        for hardware in data.hardware():
            chosen = [c for c in cells if (c.model, c.hardware) == (model, hardware)]
            if not chosen:
                continue
            chosen.sort(key=lambda c: (strategies.index(c.strategy) if c.strategy in strategies else 99,
                                       not c.training, c.world))
            tables.append(Table(f"{model} on {hardware}", "world", hardware, "", HEADERS,
                                tuple(_table_row(cells, c) for c in chosen)))
    return tables


def _table_row(cells: list[WorldCell], cell: WorldCell) -> TableRow:
    base = training_cell(cells, cell)
    lap = lap_cell(cell.lap) if cell.lap is not None else Cell(MISSING, None, "no lap", missing=True)
    tolerance = tolerance_cell(cell.lap) if cell.lap is not None else Cell(MISSING, None, "no lap", missing=True)
    mse = ratio(cell.metric("mse"), base.metric("mse") if base else None)
    deviation = ratio(cell.metric("bm_position_deviation_mae"), base.metric("bm_position_deviation_mae") if base else None)
    row = cell.lap or cell.offline
    lost = [c for c in (cell, base) if c is not None and c.metric("lap_completed") is False]
    deviation_cell = _ratio_cell(deviation, cell.training) if not lost or cell.training else \
        Cell("lap lost", None, "BM's deviation of a lost lap grows without bound (1000^d per point off the road): "
             "a ratio to it says nothing", missing=True)
    return TableRow(cell.strategy, row, (Cell(cell.world), lap, _metric(cell, "bm_position_deviation_mae"), tolerance,
                                         _metric(cell, "mse"), _ratio_cell(mse, cell.training), deviation_cell))


def shift_summary(data: ReportData) -> list[str]:
    """Per strategy: laps completed in the shifted worlds and the mean MSE ratio to the training world,
    beside the baseline's; and a verdict on the question the section asks."""
    cells = world_cells(data)
    lines = []
    for model in data.models():
        figures = {}
        for strategy in data.strategies():
            shifted = [c for c in cells if c.model == model and c.strategy == strategy and not c.training]
            if not shifted:
                continue
            # (no training-world cell: nothing to divide by; it divided each world's MSE by itself, 1.00×)
            ratios = [r for c in shifted if (home_cell := training_cell(cells, c)) is not None
                      and (r := ratio(c.metric("mse"), home_cell.metric("mse"))) is not None]
            laps = [c.metric("lap_completed") for c in shifted if c.metric("lap_completed") is not None]
            home = next((c.metric("lap_completed") for c in cells if c.model == model and c.strategy == strategy
                         and c.training), None)
            figures[strategy] = (sum(bool(x) for x in laps), len(laps),
                                 sum(ratios) / len(ratios) if ratios else None, home)
        lines += _lines(model, figures, data.baseline)
    return lines


def _lines(model: str, figures: dict, baseline: str) -> list[str]:
    lines = []
    base = figures.get(baseline)
    for strategy, (done, runs, ratio, home) in figures.items():
        mse = "offline MSE not measured in both" if ratio is None else f"offline MSE {ratio:.2f}× its training-world MSE"
        at_home = {True: "lap completed in the training world", False: "lap lost in the training world already",
                   None: "not evaluated in the training world (add it to matrix.world)"}[home]
        lines.append(f"{model}/{strategy}: {at_home}; {done}/{runs} laps completed in the shifted worlds, {mse}")
    if base is None:
        return lines
    if base[3] is not True:   # a network failing at home says nothing about what a shifted world costs
        lines.append(f"{model}: no conclusion on the world shift: " + (
            "the baseline lost its lap in its training world already" if base[3] is False else
            "the baseline was not driven in its training world (add it to matrix.world)"))
        return lines
    worse = [s for s, (done, runs, ratio, home) in figures.items() if s != baseline and
             (done < base[0] or (home is False and base[3] is True) or
              (ratio is not None and base[2] is not None and ratio > base[2] * 1.1))]
    others = [s for s in figures if s != baseline]
    if others:
        verdict = (f"{', '.join(worse)} lost more than the baseline (fewer laps, in the training world or the "
                   "shifted ones, or MSE growing over 10 % more when the world shifted)" if worse else
                   "no optimized network lost more than the baseline when the world shifted (laps completed, MSE "
                   "growth within 10 % of the baseline's)")
        lines.append(f"{model}: {verdict}")
    return lines

