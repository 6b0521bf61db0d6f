"""A quick run of the command-line fuzz (``python tools/fuzz.py --cli N`` is the long one):
bad option values and broken input files, every run one clean line or a clean result."""
from __future__ import annotations

import collections

import pytest
from cli_cases import generate, judge, make_scene
from cli_worker import run_cli_cases


@pytest.mark.slow
def test_command_line_fuzz(tmp_path):
    scene = make_scene(tmp_path / "scene")
    cases = generate(scene, tmp_path / "cases", 40, seed=3)
    results, memory = run_cli_cases([argv for argv, _, _ in cases], tmp_path, timeout=60)
    verdicts = collections.Counter(judge(case, result) for case, result in zip(cases, results))
    problems = [(case[0], result) for case, result in zip(cases, results) if judge(case, result) != "ok"]
    assert verdicts == {"ok": 40}, problems[:3]
    assert sum(1 for argv, expect, _ in cases if expect == "bad") >= 30
    assert memory["peak_mb"] < 2048
