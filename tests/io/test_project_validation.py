"""Project files are checked once, against one schema: every bad file is one InputError
naming the file and the field, never an escaped RecursionError / ValueError / OverflowError."""
from __future__ import annotations

import json
import os
import threading
from pathlib import Path

import pytest

from fluorogui.core.status import Status
from fluorogui.io import schema
from fluorogui.io.errors import InputError
from fluorogui.io.project.document import SCHEMA_VERSION, load_project, save_project

FIXTURES = Path(__file__).resolve().parent / "data"


def v2() -> dict:
    return json.loads((FIXTURES / "project_v2.fluoro").read_text())


def refusal(tmp_path, content) -> str:
    path = tmp_path / "p.fluoro"
    path.write_text(content if isinstance(content, str) else json.dumps(content))
    with pytest.raises(InputError) as info:
        load_project(path)
    message = str(info.value)
    assert message.startswith(f"{path}: ") and "\n" not in message
    return message[len(str(path)) + 2:]


def changed(change) -> dict:
    document = v2()
    change(document)
    return document


def test_the_fixture_itself_loads_and_saves(tmp_path):
    project = load_project(FIXTURES / "project_v2.fluoro")
    save_project(project, tmp_path / "p.fluoro")
    assert load_project(tmp_path / "p.fluoro") == project


def test_hostile_json(tmp_path):
    assert refusal(tmp_path, "[" * 500 + "]" * 500) == "nested more than 64 levels deep"
    deep = changed(lambda d: d["settings"].update(x=json.loads("[" * 100 + "]" * 100)))
    assert refusal(tmp_path, deep) == "nested more than 64 levels deep"
    assert refusal(tmp_path, '{"format": "fluorogui-project", "schema_version": ' + "9" * 5000 + "}") == \
        "a whole number with 5000 digits"
    text = json.dumps(v2()).replace('"image_size_px": [64, 64]', '"image_size_px": [1e999, 48]')
    assert "1e999" in text
    assert refusal(tmp_path, text) == "field 'views[0].image_size_px[0]' must be a whole number, not inf"
    text = json.dumps(changed(lambda d: d["settings"].update(x=[1]))).replace("[1]", "[1e999]")
    assert refusal(tmp_path, text) == "'settings' holds a number too large to be finite"
    assert refusal(tmp_path, json.dumps(v2()).replace("0.42", "NaN")) == "NaN is not a number JSON allows"


@pytest.mark.parametrize("change, problem", [
    (lambda d: d["views"].append(d["views"][0]), "3 views but 2 image sequences"),
    (lambda d: d["records"][0].update(frame=77), "records[0] is for frame 77, which the project does not have"),
    (lambda d: d["poses"][0].update(component="patella"), "poses[0] is for component 'patella', which has no model"),
    (lambda d: d["models"][0].update(point_density=-5), "field 'models[0].point_density' must be >= 10, not -5"),
    (lambda d: d["models"][0].update(point_density=10**12),
     "field 'models[0].point_density' must be <= 10000000, not 1000000000000"),
    (lambda d: d["poses"][0].update(pose=["1.5", -2, 3, 10, -20, 5]),
     "field 'poses[0].pose[0]' must be a number, not '1.5'"),
    (lambda d: d["models"][0].update(point_density="15000"),
     "field 'models[0].point_density' must be a whole number, not '15000'"),
    (lambda d: d["views"][0].update(principal_point_px=[1, 2, 3]),
     "field 'views[0].principal_point_px' has 3 values, more than the 2 allowed"),
    (lambda d: d["views"][0].update(image_size_px=[0, 48]), "field 'views[0].image_size_px[0]' must be >= 1, not 0"),
    (lambda d: d["frames"].append(d["frames"][0]), "frames: a frame number is listed twice"),
    (lambda d: d["sequences"][0]["paths"].extend(["x.tif"] * 5), "sequences[0] has 7 images for 2 frames"),
    (lambda d: d["records"][0].update(reviewed=1), "field 'records[0].reviewed' must be true or false, not 1"),
    (lambda d: d.update(settings={"gui": []}), "field 'settings.gui' must be an object, not a list of 0"),
    (lambda d: d.update(settings={"gui": True}), "field 'settings.gui' must be an object, not True"),
    (lambda d: d.update(settings={"workflow": {"match": 3}}),
     "field 'settings.workflow.match' must be an object, not 3"),
    (lambda d: d["models"][0].update(component=""), "field 'models[0].component' must not be empty"),
    (lambda d: d["poses"][0]["match"].update(calls=-1), "field 'poses[0].match.calls' must be >= 0, not -1"),
    (lambda d: d.update(views="many"), "field 'views' must be a list, not 'many'"),
])
def test_inconsistent_or_mistyped_sessions_are_refused(tmp_path, change, problem):
    assert refusal(tmp_path, changed(change)) == problem


def test_spline_counts_must_agree(tmp_path):
    project = v2()
    project["records"][0]["spline"] = {"knots": [0, 0, 0, 0, 1, 1, 1, 1], "coefficients": [[1, 2, 3], [1, 2, 3]],
                                       "degree": 3, "t_range": [0, 1]}
    assert refusal(tmp_path, project) == "field 'records[0].spline': 8 knots do not fit 3 coefficients of degree 3"
    project["records"][0]["spline"]["coefficients"] = [[1, 2, 3, 4], [1, 2, 3, 4]]
    path = tmp_path / "ok.fluoro"
    path.write_text(json.dumps(project))
    assert load_project(path).records[(0, 0, "femur")].spline.degree == 3


@pytest.mark.skipif(not hasattr(os, "mkfifo"), reason="POSIX FIFOs")
def test_fifo_is_refused_without_blocking(tmp_path):
    fifo = tmp_path / "p.fluoro"
    os.mkfifo(fifo)
    outcome = []
    worker = threading.Thread(target=lambda: outcome.append(_message(fifo)), daemon=True)
    worker.start()
    worker.join(5)
    assert outcome == [f"{fifo}: is not a regular file (a pipe, socket or device); give a project file"]


def _message(path) -> str:
    try:
        load_project(path)
    except InputError as exc:
        return str(exc)
    return "accepted"


def test_folder_and_huge_file(tmp_path, monkeypatch):
    refused = str(pytest.raises(InputError, load_project, tmp_path).value)
    assert refused == f"{tmp_path}: is a folder, not a project file"
    monkeypatch.setattr("fluorogui.io.project.document.MAX_PROJECT_BYTES", 100)
    path = tmp_path / "big.fluoro"
    path.write_text(" " * 2_000_000)
    assert str(pytest.raises(InputError, load_project, path).value) == \
        f"{path}: project file is too large (2 MB; at most 0 MB)"


def test_schema_knows_the_statuses_of_the_engine():
    assert set(schema.POSE_STATUSES) == {s.value for s in Status}


def test_nesting_depth_skips_brackets_in_strings():
    assert schema.nesting_depth('{"a": "[[[[[[", "b": [[1]], "c": "\\"]]"}') == 3


def test_packed_arrays_are_written_and_checked(tmp_path):
    project = load_project(FIXTURES / "project_v2.fluoro")
    path = tmp_path / "saved.fluoro"
    save_project(project, path)
    document = json.loads(path.read_text())
    packed = document["records"][0]["points"]
    assert document["schema_version"] == SCHEMA_VERSION and set(packed) == {"dtype", "shape", "base64"}
    assert load_project(path) == project  # exact float64

    def broken(change) -> str:
        bad = json.loads(path.read_text())
        change(bad["records"][0]["points"])
        return refusal(tmp_path, bad)

    assert broken(lambda p: p.update(base64="%%%")) == \
        "field 'records[0].points': the packed array's data is not valid base64"
    assert broken(lambda p: p.update(shape=[3, 2])).startswith(
        "field 'records[0].points': the packed array holds")
    assert broken(lambda p: p.update(dtype="<f4")) == \
        "field 'records[0].points': must be a list of numbers or a packed array (<f8)"


def test_list_arrays_of_older_files_are_checked_with_numpy(tmp_path):
    def points(value) -> dict:
        return changed(lambda d: d["records"][0].update(points=value))

    assert refusal(tmp_path, points([["1", "2"]])) == \
        "field 'records[0].points': must be a Nx2 array of numbers (not text, true/false or null)"
    assert refusal(tmp_path, points([[1, 2], [3]])) == \
        "field 'records[0].points': must be a regular Nx2 array of numbers"
    assert refusal(tmp_path, points([[1, 2, 3]])) == "field 'records[0].points': must be a Nx2 array, got shape 1x3"
    assert refusal(tmp_path, points([[True, False]])) == \
        "field 'records[0].points': must be a Nx2 array of numbers (not text, true/false or null)"
    assert refusal(tmp_path, points([[1e300, 0]])) == "field 'records[0].points': holds numbers beyond ±1e+07"


@pytest.mark.parametrize("section, key, value, problem", [
    ("match", "starts", "3", "must be a whole number from 0 to 10^9, not '3'"),
    ("match", "xtol", -1.0, "must be a finite number from 0 to 10^9, not -1.0"),
    ("match", "symmetric", 1, "must be true or false, not 1"),
    ("match", "restart_sd", [5.0], "must be a list of 2 numbers, not a list of 1"),
    ("loop", "max_passes", 2.5, "must be a whole number from 0 to 10^9, not 2.5"),
    ("quality", "max_view_mm", None, "must be a finite number from 0 to 10^9, not None"),
    ("tracking", "occlusion_margin_px", "3", "must be a whole number from 0 to 10^9, not '3'"),
    ("tracking", "probe", 1, "must be true or false, not 1"),
    ("tracking", "max_seconds", -5.0, "must be a finite number from 0 to 10^9, not -5.0"),
])
def test_engine_settings_of_the_wrong_kind_are_refused(tmp_path, section, key, value, problem):
    document = changed(lambda d: d["settings"].update(workflow={section: {key: value}}))
    assert refusal(tmp_path, document) == f"field 'settings.workflow.{section}.{key}' {problem}"


def test_engine_settings_that_fluorogui_writes_are_accepted(tmp_path):
    from fluorogui.workflow.settings import WorkflowSettings

    document = changed(lambda d: d["settings"].update(workflow=WorkflowSettings().to_dict(), gui={"zoom": 2}))
    path = tmp_path / "p.fluoro"
    path.write_text(json.dumps(document))
    assert load_project(path).settings["workflow"] == json.loads(json.dumps(WorkflowSettings().to_dict()))
