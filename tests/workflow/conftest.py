"""A demo session built once per test run, with frame 0 matched from its rough start, copied
into each test's folder (so tests may change it freely)."""
from __future__ import annotations

import shutil
from pathlib import Path

import numpy as np
import pytest

from fluorogui.simulation.demo import build_demo_project
from fluorogui.workflow import Session


@pytest.fixture(scope="session")
def demo_master(tmp_path_factory) -> Path:
    """The demo folder with frame 0 of both components matched and saved."""
    folder = tmp_path_factory.mktemp("demo_master")
    path = build_demo_project(folder)
    session = Session.open(path)
    results = session.match(0)
    assert [r.status for r in results] == ["matched", "matched"], [r.reason for r in results]
    session.save()
    return path


@pytest.fixture
def demo(demo_master, tmp_path) -> Path:
    """A private copy of the matched demo; returns its project file."""
    target = tmp_path / "demo"
    shutil.copytree(demo_master.parent, target)
    return target / demo_master.name


@pytest.fixture
def truth():
    """truth(session) -> {frame: {component: pose}} of a demo session."""
    def of(session: Session) -> dict:
        return {int(f): {c: np.asarray(p, float) for c, p in by.items()}
                for f, by in session.project.settings["demo_truth"].items()}
    return of
