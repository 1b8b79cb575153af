"""The report writer: tables of the 2022 study's shape, plots, README.md, index.html and tidy results.

    from pilotlab.report import ReportData, write_report
    paths = write_report(ReportData.from_dict(plain_dicts), Path("reports/quickstart"))

See `pilotlab.report.data` for the fields of `ReportData` and how to build it from job results.
"""
from pilotlab.report.data import (HistoryPoint, Host, ReportData, ReportDataError, ReportRow,  # noqa: F401
                                  Spread, package_versions, pick_metrics, pick_spread)
from pilotlab.report.writer import ReportPaths, write_report  # noqa: F401
