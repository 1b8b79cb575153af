"""Fixtures: the study-like report data of toy.py, and that report written once per session."""
from __future__ import annotations

from pathlib import Path

import pytest

from pilotlab.report import ReportData, ReportPaths, write_report
from tests.pilotlab.report.toy import study_dict


@pytest.fixture
def study(tmp_path: Path) -> ReportData:
    pictures = tmp_path / "pictures"
    pictures.mkdir()
    return ReportData.from_dict(study_dict(pictures))


@pytest.fixture(scope="session")
def study_report(tmp_path_factory) -> tuple[ReportData, ReportPaths]:
    """The study-like report written once per test session (tests only read it)."""
    root = tmp_path_factory.mktemp("study")
    (root / "pictures").mkdir()
    data = ReportData.from_dict(study_dict(root / "pictures"))
    return data, write_report(data, root / "report")
