"""Every loader on mutated files (flipped bytes, cuts, junk, repeated slices, odd numbers):
a loader either accepts a file or refuses it with one line naming it; no crash, no hang,
no other exception. The loaders run in a child process so a C library's crash is counted,
not fatal. Quick here; ``python tools/fuzz.py`` runs the long version."""
from __future__ import annotations

import json

import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from loader_worker import fuzz_loaders
from seeds import make_seeds

from fluorogui.io.errors import InputError
from fluorogui.io.outlines import read_outline_csv
from fluorogui.io.pose_files import read_reference_poses


@pytest.mark.slow
def test_mutated_files_of_every_loader(tmp_path):
    seeds = make_seeds(tmp_path / "seeds")
    (tmp_path / "cases").mkdir()
    counts = fuzz_loaders(seeds, tmp_path / "cases", per_seed=4, seed=11)
    assert counts["cases"] == 4 * sum(len(files) for files in seeds.values())
    problems = {k: counts[k] for k in ("escaped", "crashes", "hangs", "unnamed")}
    assert problems == {"escaped": 0, "crashes": 0, "hangs": 0, "unnamed": 0}, json.dumps(counts["examples"])
    assert counts["refused"] > counts["cases"] // 2  # the mutations are mostly fatal, and caught


CELLS = st.one_of(st.text(max_size=6), st.floats().map(str), st.integers().map(str), st.sampled_from(["nan", "1e999"]))


@settings(max_examples=60, deadline=None)
@given(rows=st.lists(st.lists(CELLS, min_size=0, max_size=9), max_size=5), header=st.booleans())
def test_reference_tables(tmp_path_factory, rows, header):
    path = tmp_path_factory.mktemp("ref") / "ref.csv"
    lines = (["frame,component,x,y,z,alpha,beta,gamma"] if header else []) + [
        ",".join(c.replace(",", ";").replace("\n", " ").replace("\r", " ").replace('"', "") for c in row)
        for row in rows]
    path.write_text("\n".join(lines), encoding="utf-8")
    try:
        poses = read_reference_poses(path)
    except InputError as exc:
        assert str(exc).startswith(f"{path}: ") and "\n" not in str(exc)
        return
    for _frame, _component, pose in poses:
        assert pose.shape == (6,) and all(abs(v) <= 1e7 for v in pose)


@settings(max_examples=60, deadline=None)
@given(text=st.text(alphabet=st.sampled_from("0123456789.,;-e \t\nnaifu#"), max_size=200))
def test_outline_files(tmp_path_factory, text):
    path = tmp_path_factory.mktemp("outline") / "o.csv"
    path.write_text(text, encoding="utf-8")
    try:
        points = read_outline_csv(path)
    except InputError as exc:
        assert str(exc).startswith(f"{path}: ") and "\n" not in str(exc)
        return
    assert points.ndim == 2 and points.shape[1] == 2 and (points.size == 0 or abs(points).max() <= 1e6)
