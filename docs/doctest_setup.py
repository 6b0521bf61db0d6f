"""A pytest plugin for the doctests ``docs/build.sh`` runs (``-p doctest_setup``).

The examples in the public API's docstrings are written as a user would type them in a
scratch folder: they build the demo there (``fluorogui.simulation.demo.demo_project_path``
builds it once and reuses it). This plugin gives them that folder: one temporary folder
for the whole run, the working directory while the examples run.
"""
from __future__ import annotations

import os

import numpy as np
import pytest


@pytest.fixture(autouse=True, scope="session")
def _scratch_folder(tmp_path_factory):
    folder = tmp_path_factory.mktemp("doctests")
    before = os.getcwd()
    os.chdir(folder)
    np.set_printoptions(precision=3, suppress=True, legacy="1.25")
    try:
        yield folder
    finally:
        os.chdir(before)
