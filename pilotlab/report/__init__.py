"""The report writer: tables of the 2022 study's shape, plots, README.md, index.html and tidy results.

    from pilotlab.report import ReportData, write_report
    paths = write_report(ReportData.from_dict(plain_dicts), Path("reports/quickstart"))

See `pilotlab.report.data` for the fields of `ReportData` and how to build it from job results.
"""
from pilotlab.report.data import (HistoryPoint, Host, ReportData, ReportDataError, ReportRow,  # noqa: F401
                                  Spread, package_versions, pick_metrics, pick_spread)

_WRITER = ("ReportPaths", "write_report")


def __getattr__(name: str):
    """The writer's names, imported on first use: it loads matplotlib (~0.5 s), which a warm
    `pilotlab run` deciding that its report is up to date never needs."""
    if name in _WRITER:
        from pilotlab.report import writer
        return getattr(writer, name)
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")
