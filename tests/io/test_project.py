"""Project files: round trip, schema migration, atomic save, and refusal of bad files."""
from __future__ import annotations

import errno
import json
import os
from pathlib import Path

import numpy as np
import pytest

from fluorogui.core.projection.geometry import View
from fluorogui.core.records import (
    ImageSequence,
    MatchRecord,
    ModelEntry,
    OutlineRecord,
    PoseRecord,
    Project,
    SplineRecord,
)
from fluorogui.io.errors import InputError
from fluorogui.io.project import document as project_io
from fluorogui.io.project.document import MIGRATIONS, SCHEMA_VERSION, load_project, save_project

FIXTURES = Path(__file__).resolve().parent / "data"


def full_project(root: Path) -> Project:
    rng = np.random.default_rng(3)
    views = [
        View.looking_at((0, -1000, 0), (0, 0, 0), (0, 0, 1), 1200, image_size=(64, 48), pitch=0.4, name="cam1"),
        View.looking_at((800, -600, 0), (0, 0, 0), (0, 0, 1), 1150, image_size=(64, 48), pitch=0.4, name="cam2"),
    ]
    sequences = [
        ImageSequence([root / "images" / "cam1" / f"{i:03d}.tif" for i in range(3)]),
        ImageSequence([root.parent / "elsewhere" / f"b{i}.png" for i in range(3)]),
    ]
    frame = np.eye(4)
    frame[:3, 3] = [1.25, -3.5, 7.0]
    models = [
        ModelEntry("femur", root / "models" / "fem.stl", 15000, frame),
        ModelEntry("tibia", root / "models" / "tib.stl", 3500),
    ]
    spline = SplineRecord(rng.random(11), rng.random((2, 7)) * 60, 3, (0.0, 1.0 / 3.0))
    records = {
        (0, 0, "femur"): OutlineRecord(rng.random((40, 2)) * 60, spline, True),
        (0, 1, "femur"): OutlineRecord(rng.random((35, 2)) * 60, None, False, weights=rng.random(35) + 0.05),
        (2, 1, "tibia"): OutlineRecord(np.empty((0, 2)), None, False),
    }
    match = MatchRecord(0.123456789, [0.06, 0.063456789], 651, 113.25, False, "paper-bfgs", {"outline_points": 60})
    poses = {
        (0, "femur"): PoseRecord(rng.normal(size=6) * 10, match),
        (2, "tibia"): PoseRecord(np.zeros(6), None),
    }
    settings = {"canny": {"low": 0.1, "high": 0.3}, "density": "15k", "units": ["mm", "deg"]}
    return Project(views, sequences, [0, 1, 2], models, records, poses, settings)


def test_round_trip(tmp_path):
    original = full_project(tmp_path)
    path = tmp_path / "knee.fluoro"
    save_project(original, path)
    loaded = load_project(path)
    assert loaded == original
    for key, record in original.records.items():
        np.testing.assert_allclose(loaded.records[key].points, record.points)
    np.testing.assert_allclose(loaded.poses[(0, "femur")].pose, original.poses[(0, "femur")].pose)
    # paths are stored relative to the project file
    document = json.loads(path.read_text())
    assert document["sequences"][0]["paths"][0] == "images/cam1/000.tif"
    assert document["sequences"][1]["paths"][0].startswith("../elsewhere/")
    assert document["models"][0]["mesh_path"] == "models/fem.stl"
    assert document["schema_version"] == SCHEMA_VERSION


def test_moved_project_resolves_paths_against_its_folder(tmp_path):
    (tmp_path / "a").mkdir()
    save_project(full_project(tmp_path / "a"), tmp_path / "a" / "p.fluoro")
    (tmp_path / "b").mkdir()
    os.replace(tmp_path / "a" / "p.fluoro", tmp_path / "b" / "p.fluoro")
    loaded = load_project(tmp_path / "b" / "p.fluoro")
    assert loaded.models[0].mesh_path == tmp_path / "b" / "models" / "fem.stl"


def test_fixtures_v1_and_v2_load_to_the_same_project():
    v1 = load_project(FIXTURES / "project_v1.fluoro")
    v2 = load_project(FIXTURES / "project_v2.fluoro")
    assert v1 == v2
    assert set(v1.records) == {(0, 0, "femur"), (1, 1, "tibia")}
    assert v1.settings == {}
    assert v1.records[(0, 0, "femur")].spline.t_range == (0.0, 4.0)
    assert v1.poses[(0, "femur")].match.calls == 312
    assert v1.sequences[1].paths[0] == FIXTURES / "images" / "cam2" / "frame_000.png"
    assert v1.models[1].mesh_path == FIXTURES.parent / "shared_models" / "tibia.stl"


def test_migration_chain_is_complete():
    assert sorted(MIGRATIONS) == list(range(1, SCHEMA_VERSION))
    document = json.loads((FIXTURES / "project_v1.fluoro").read_text())
    before = json.dumps(document)
    upgraded = project_io.upgrade(document)
    assert json.dumps(document) == before  # the input is left alone
    assert upgraded["schema_version"] == SCHEMA_VERSION and "outlines" not in upgraded


def test_save_keeps_backup(tmp_path):
    path = tmp_path / "p.fluoro"
    project = full_project(tmp_path)
    save_project(project, path)
    first = path.read_text()
    project.frames.append(3)
    save_project(project, path)
    assert (tmp_path / "p.fluoro.bak").read_text() == first
    assert load_project(path).frames == [0, 1, 2, 3]
    assert not list(tmp_path.glob(".p.fluoro.*"))


@pytest.mark.parametrize("where", ["replace", "write"])
def test_failed_save_leaves_previous_file(tmp_path, monkeypatch, where):
    path = tmp_path / "p.fluoro"
    project = full_project(tmp_path)
    save_project(project, path)
    before = path.read_text()

    def disk_full(*args, **kwargs):
        raise OSError(errno.ENOSPC, "No space left on device")

    if where == "replace":
        monkeypatch.setattr(os, "replace", disk_full)
    else:
        monkeypatch.setattr(os, "fsync", disk_full)
    project.frames.append(99)
    with pytest.raises(InputError) as info:
        save_project(project, path)
    assert str(info.value) == f"{path}: could not save: disk full"
    monkeypatch.undo()
    assert path.read_text() == before
    assert not list(tmp_path.glob(".p.fluoro.*"))  # the temporary file is gone


def test_save_into_missing_folder(tmp_path):
    path = tmp_path / "no" / "such" / "p.fluoro"
    with pytest.raises(InputError, match="could not save: file or folder not found"):
        save_project(full_project(tmp_path), path)


def test_save_refuses_nan(tmp_path):
    project = full_project(tmp_path)
    project.poses[(0, "femur")].pose[0] = np.nan
    with pytest.raises(InputError, match="NaN or infinite"):
        save_project(project, tmp_path / "p.fluoro")
    assert not (tmp_path / "p.fluoro").exists()


# -- refusing bad files ---------------------------------------------------------------------------------
def load_error(path) -> str:
    with pytest.raises(InputError) as info:
        load_project(path)
    message = str(info.value)
    assert message.startswith(f"{path}: ") and "\n" not in message
    return message


def test_truncated(tmp_path):
    path = tmp_path / "p.fluoro"
    save_project(full_project(tmp_path), path)
    text = path.read_text()
    path.write_text(text[: len(text) // 2])
    assert load_error(path).endswith("file is truncated or not valid JSON")


def test_not_ours(tmp_path):
    for i, content in enumerate(['{"format": "other"}', "[1, 2, 3]", '"text"']):
        path = tmp_path / f"x{i}.fluoro"
        path.write_text(content)
        assert load_error(path).endswith("not a fluorogui project")
    (tmp_path / "bin.fluoro").write_bytes(b"\xff\xfe\x00garbage")
    assert "not a fluorogui project" in load_error(tmp_path / "bin.fluoro")
    assert load_error(tmp_path / "none.fluoro").endswith("file not found")


def test_newer_schema(tmp_path):
    path = tmp_path / "p.fluoro"
    path.write_text(json.dumps({"format": "fluorogui-project", "schema_version": SCHEMA_VERSION + 1}))
    assert load_error(path).endswith(
        f"written by a newer fluorogui (schema {SCHEMA_VERSION + 1} > {SCHEMA_VERSION}); update fluorogui to open it"
    )


def edited(tmp_path, change) -> Path:
    document = json.loads((FIXTURES / "project_v2.fluoro").read_text())
    change(document)
    path = tmp_path / "p.fluoro"
    path.write_text(json.dumps(document))
    return path


def test_missing_and_malformed_fields(tmp_path):
    assert load_error(edited(tmp_path, lambda d: d.pop("views"))).endswith("missing the field 'views'")
    assert load_error(edited(tmp_path, lambda d: d["records"][1].pop("points"))).endswith(
        "missing the field 'records[1].points'"
    )
    assert "field 'poses[0].pose' has 3 values, fewer than the 6 it needs" in load_error(
        edited(tmp_path, lambda d: d["poses"][0].update(pose=[1, 2, 3]))
    )
    assert "'views[1]': normal is not a unit vector" in load_error(
        edited(tmp_path, lambda d: d["views"][1].update(normal=[2.0, 0.0, 0.0]))
    )
    assert "NaN is not a number JSON allows" in load_error(
        edited(tmp_path, lambda d: d["records"][0]["points"][0].__setitem__(0, float("nan")))
    )
    assert "records[1] is for view 5 but the project has 2 views" in load_error(
        edited(tmp_path, lambda d: d["records"][1].update(view=5))
    )
    error = load_error(edited(tmp_path, lambda d: d.update(settings=[])))
    assert "field 'settings' must be an object, not a list of 0" in error
    points = len(json.loads((FIXTURES / "project_v2.fluoro").read_text())["records"][0]["points"])
    assert f"3 weights for {points} points" in load_error(
        edited(tmp_path, lambda d: d["records"][0].update(weights=[1.0, 2.0, 3.0])))
    assert "weights must be positive" in load_error(
        edited(tmp_path, lambda d: d["records"][0].update(weights=[0.0] * points)))


def test_v1_with_bad_key(tmp_path):
    document = json.loads((FIXTURES / "project_v1.fluoro").read_text())
    document["outlines"][0]["key"] = "zero/0/femur"
    path = tmp_path / "old.fluoro"
    path.write_text(json.dumps(document))
    assert "cannot upgrade from schema 1: 'outlines[0].key' must start with two whole numbers" in load_error(path)


def test_schema_2_poses_get_a_status_that_never_shows_unconverged_as_matched():
    document = json.loads((FIXTURES / "project_v2.fluoro").read_text())
    document["poses"][0]["match"]["converged"] = False
    upgraded = project_io.upgrade(document)
    statuses = {(p["frame"], p["status"], p["reason"]) for p in upgraded["poses"]}
    assert statuses == {(0, "needs_review", "the match did not converge"), (1, "placed", "")}
    project = load_project(FIXTURES / "project_v2.fluoro")
    assert project.poses[(0, "femur")].status == "matched" and project.poses[(0, "femur")].is_matched
    assert project.poses[(1, "tibia")].status == "placed" and not project.poses[(1, "tibia")].is_matched


def test_status_reason_and_quality_round_trip(tmp_path):
    project = full_project(tmp_path)
    record = project.poses[(0, "femur")]
    record.match.quality = {"edge_support": [0.99, 0.42], "jump_mm": 0.5}
    record.match.history = [0.5, 0.21, 0.125]
    project.poses[(0, "femur")] = PoseRecord(record.pose, record.match, status="needs_review",
                                             reason="only 42 % of the model outline lies on image edges in view 2")
    project.poses[(1, "tibia")] = PoseRecord(np.ones(6), None, status="failed", reason="view 2: image missing")
    save_project(project, tmp_path / "p.fluoro")
    again = load_project(tmp_path / "p.fluoro")
    assert again == project
    assert again.poses[(0, "femur")].needs_review and again.poses[(1, "tibia")].needs_review
    assert again.poses[(0, "femur")].match.quality["edge_support"] == [0.99, 0.42]
    assert again.poses[(0, "femur")].match.history == [0.5, 0.21, 0.125]
    text = (tmp_path / "p.fluoro").read_text()
    bad = text.replace('"status":"failed"', '"status":"fine"')
    assert bad != text
    (tmp_path / "bad.fluoro").write_text(bad)
    with pytest.raises(InputError, match="status"):
        load_project(tmp_path / "bad.fluoro")


def test_schema_4_rim_switch_loads_as_a_rim_mode(tmp_path):
    from fluorogui.workflow.settings import WorkflowSettings

    path = tmp_path / "old.fluoro"
    save_project(full_project(tmp_path), path)
    document = json.loads(path.read_text())
    for stored, mode in ((False, "auto"), (True, "on")):  # schema 4's default was False
        document.update(schema_version=4, settings={"workflow": {"loop": {"min_passes": 3, "rim": stored}}})
        path.write_text(json.dumps(document))
        settings = WorkflowSettings.from_dict(load_project(path).settings["workflow"])
        assert settings.loop.rim == mode and settings.loop.min_passes == 3
    document.update(schema_version=SCHEMA_VERSION, settings={"workflow": {"loop": {"rim": "sometimes"}}})
    path.write_text(json.dumps(document))
    with pytest.raises(InputError, match="settings.workflow.loop.*rim must be one of auto, on, off"):
        load_project(path)
