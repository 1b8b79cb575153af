"""The report writer: tables of the 2022 study's shape, plots, README.md, index.html and tidy results.

    from pilotlab.report import ReportData, write_report
    paths = write_report(ReportData.from_dict(plain_dicts), Path("reports/quickstart"))

See `pilotlab.report.data` for the fields of `ReportData` and how to build it from job results.
"""
_MODULES = {"writer": ("ReportPaths", "write_report"),
            "data": ("HistoryPoint", "Host", "ReportData", "ReportDataError", "ReportRow", "Spread",
                     "package_versions", "pick_metrics", "pick_spread")}


def __getattr__(name: str):
    """The names, imported on first use: the writer loads matplotlib (~0.5 s), which a warm
    `pilotlab run` deciding that its report is up to date never needs, and planning a recipe that
    names a study to compare with (pilotlab.report.studies) needs neither module."""
    module = next((module for module, names in _MODULES.items() if name in names), None)
    if module is not None:
        import importlib
        return getattr(importlib.import_module(f"{__name__}.{module}"), name)
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")
