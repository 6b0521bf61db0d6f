"""A project file never loads contradicting itself: views with fewer images than frames say
so (schema 6), older files that did not are repaired with a warning, keys are never given
twice, and the arrays' counts are checked against the frames before they are allocated.
The refusals of each contradiction the fuzz run found are in ``tests/fuzz`` (regressions)."""
from __future__ import annotations

import json
import warnings
from pathlib import Path

import numpy as np
import pytest

from fluorogui.core.records import ImageSequence
from fluorogui.io import schema
from fluorogui.io.errors import InputError, InputWarning
from fluorogui.io.plausible import rigid_problem, view_problem
from fluorogui.io.project.document import SCHEMA_VERSION, load_project, project_to_document, save_project

FIXTURES = Path(__file__).resolve().parent / "data"


def short_project():
    """The fixture with camera 2 one image short, as ``fluorogui import`` may make it."""
    project = load_project(FIXTURES / "project_v2.fluoro")
    project.sequences[1] = ImageSequence(project.sequences[1].paths[:1])
    return project


def test_a_view_with_fewer_images_than_frames_says_so(tmp_path):
    path = tmp_path / "p.fluoro"
    with warnings.catch_warnings():
        warnings.simplefilter("error")  # a current file loads without a warning
        save_project(short_project(), path)
        document = json.loads(path.read_text())
        assert document["schema_version"] == SCHEMA_VERSION == 6
        assert document["sequences"][1]["frames_without_image"] == [1]
        assert "frames_without_image" not in document["sequences"][0]
        assert load_project(path) == short_project()


def test_a_schema_5_file_with_a_short_view_is_repaired_with_a_warning(tmp_path):
    document = project_to_document(short_project(), tmp_path)
    document["schema_version"] = 5
    del document["sequences"][1]["frames_without_image"]
    path = tmp_path / "old.fluoro"
    path.write_text(json.dumps(document))
    with pytest.warns(InputWarning) as caught:
        project = load_project(path)
    assert project == short_project()
    assert [str(w.message) for w in caught] == [
        f"{path}: view 2 has 1 of the 2 frames' images (schema 5 allowed it silently): frame 1 will be flagged "
        "when matched; saving states this in the file (sequences[1].frames_without_image)"]


@pytest.mark.parametrize("stated, words", [
    ([0], "must be [1], not [0]"),
    ([1, 2], "must be [1], not [1, 2]"),
])
def test_the_frames_without_an_image_must_be_the_last_ones(tmp_path, stated, words):
    document = project_to_document(short_project(), tmp_path)
    document["sequences"][1]["frames_without_image"] = stated
    path = tmp_path / "p.fluoro"
    path.write_text(json.dumps(document))
    with pytest.raises(InputError, match=rf"^{path}: sequences\[1\] has 1 image for 2 frames, .*"):
        load_project(path)
    with pytest.raises(InputError) as info:
        load_project(path)
    assert str(info.value).endswith(words)


def test_keys_given_twice_are_refused_anywhere():
    with pytest.raises(schema.DocumentError, match="^the key 'a' appears twice in one object$"):
        schema.parse_json('{"x": [{"a": 1, "b": 2, "a": 1}]}')
    assert schema.parse_json('{"a": {"a": 1}}') == {"a": {"a": 1}}  # one key per object is fine


def test_items_are_counted_before_anything_is_allocated():
    assert schema.json_structure('{"a": "[[,,", "b": [[1, 2]], "c": "\\"]]"}') == (3, 6, 3)
    with pytest.raises(schema.DocumentError, match="^holds 10 JSON values, more than the 5 fluorogui reads"):
        schema.parse_json("[{}, {}, {}, {}, {}]", most_items=5)
    members = ", ".join(f'"k{i}": 0' for i in range(schema.MAX_OBJECT_MEMBERS + 1))
    with pytest.raises(schema.DocumentError, match="^an object has 100,001 members; fluorogui's have at most a few"):
        schema.parse_json('{"settings": {"gui": {' + members + "}}}")


def test_the_structure_is_the_same_read_in_blocks(monkeypatch):
    """Strings, escapes and objects cut by a block's end are followed into the next block."""
    text = json.dumps({"a": ['x,"]{', {"b": "\\", "c": [1, 2, {"d": 3, "e": "\\\"}"}]}], "f": {}})
    whole = schema.json_structure(text)
    assert whole == (5, 12, 2)
    for block in (1, 2, 3, 7):
        monkeypatch.setattr(schema, "_BLOCK", block)
        assert schema.json_structure(text) == whole


def test_arrays_beyond_what_the_frames_hold_are_refused_before_their_items_are_read(tmp_path):
    document = project_to_document(load_project(FIXTURES / "project_v2.fluoro"), tmp_path)
    document["poses"] += [None] * 100_000  # never read one by one: the count alone refuses the file
    path = tmp_path / "p.fluoro"
    path.write_text(json.dumps(document))
    with pytest.raises(InputError) as info:
        load_project(path)
    assert str(info.value) == f"{path}: poses holds 100,002 poses, more than the 2 frames x 2 components can hold"


@pytest.mark.parametrize("matrix, problem", [
    (np.eye(4), None),
    (np.diag([1000.0, 1000.0, 1000.0, 1.0]), "scale 1000"),
    (np.diag([1.0, 2.0, 3.0, 1.0]), "scales 3, 2, 1"),
    (np.diag([1.0, 1.0, -1.0, 1.0]), "a reflection"),
    (np.zeros((4, 4)), "scale 0"),
])
def test_rigid_transforms(matrix, problem):
    assert rigid_problem(matrix) == problem


def test_every_view_of_the_suite_and_the_real_data_is_plausible():
    from fluorogui.core.projection.geometry import View

    views = [View.looking_at((0, -1000, 0), (0, 0, 0), (0, 0, 1), 1200, image_size=(64, 48), pitch=0.4),
             View.looking_at([0, -1000, 0], [0, 0, 0], [0, 0, 1], 1200.0, image_size=(64, 48), pitch=3.0),
             View.looking_at([0, 0, -1000], [0, 0, 0], [0, -1, 0], 1000.0, image_size=(1024, 1024), pitch=315 / 1024)]
    assert [view_problem(v) for v in views] == [None] * 3
    narrow = View.looking_at((0, -1000, 0), (0, 0, 0), (0, 0, 1), 1200, image_size=(8, 8), pitch=0.001)
    assert view_problem(narrow)[0] == "focal"
