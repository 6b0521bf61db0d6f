"""Hand-made nasty project files (built from the small valid fixture, so the corpus stays a
few kilobytes): each is a name and the file's text. Every one must be refused with one
InputError naming the file, by the loader and by the app's open path.

``REGRESSIONS`` are the cases of the issue "project files that break their own invariants"
(a fuzz run found each loading, the contradiction kept), at the current schema, with the
words their one-line refusal must hold."""
from __future__ import annotations

import json
from pathlib import Path

FIXTURE = Path(__file__).resolve().parents[1] / "io" / "data" / "project_v2.fluoro"


def _base() -> dict:
    return json.loads(FIXTURE.read_text())


def _edit(change) -> str:
    document = _base()
    change(document)
    return json.dumps(document)


def _current() -> dict:
    """The fixture as the current schema writes it (the issue's cases are of that schema)."""
    from fluorogui.io.project.document import load_project, project_to_document

    return json.loads(json.dumps(project_to_document(load_project(FIXTURE), FIXTURE.parent)))


def _now(change) -> str:
    document = _current()
    change(document)
    return json.dumps(document)


def _twice(key: str, first) -> str:
    """The current document with ``key`` given a first time (``first``) before its real value."""
    text = json.dumps(_current())
    return "{" + json.dumps(key) + ": " + json.dumps(first) + ", " + text[1:]


def regressions() -> list[tuple[str, str, str]]:
    """(name, text, words of the refusal) for each contradiction of the issue."""
    scaled = [[1000.0, 0, 0, 0], [0, 1000.0, 0, 0], [0, 0, 1000.0, 0], [0, 0, 0, 1.0]]
    fives = [[1.0, 0, 0, 0], [0, 1.0, 0, 0], [0, 0, 1.0, 0], [5.0, 5.0, 5.0, 5.0]]
    return [
        ("sequence_shorter_than_frames", _now(lambda d: d["sequences"][1]["paths"].pop()),
         "sequences[1] has 1 image for 2 frames, so its 'frames_without_image' must be [1], not []"),
        ("local_frame_scaled_1000", _now(lambda d: d["models"][0].update(local_frame=scaled)),
         "models[0].local_frame is not a rigid transform (scale 1000)"),
        ("local_frame_zeros", _now(lambda d: d["models"][0].update(local_frame=[[0.0] * 4] * 4)),
         "models[0].local_frame is not a rigid transform (scale 0)"),
        ("local_frame_bottom_row_5s", _now(lambda d: d["models"][1].update(local_frame=fives)),
         "models[1].local_frame is not a rigid transform (bottom row 5, 5, 5, 5; a rigid transform's is 0, 0, 0, 1)"),
        ("source_distance_1e-300", _now(lambda d: d["views"][0].update(distance_mm=1e-300)),
         "views[0].distance_mm: source-intensifier distance 1e-300 mm is not plausible for a fluoroscope"),
        ("five_per_view_values", _now(lambda d: d["poses"][0]["match"].update(per_view_mean_mm=[0.1] * 5)),
         "poses[0].match.per_view_mean_mm has 5 values for the project's 2 views"),
        ("mesh_path_nul", _now(lambda d: d["models"][0].update(mesh_path="models/fe\x00mur.stl")),
         "models[0].mesh_path holds a NUL character"),
        ("image_path_nul", _now(lambda d: d["sequences"][0]["paths"].__setitem__(1, "images/a\x00.png")),
         "sequences[0].paths[1] holds a NUL character"),
        ("schema_version_twice", _twice("schema_version", 1), "the key 'schema_version' appears twice in one object"),
        ("key_twice_in_a_pose", _now(lambda d: None).replace('"reviewed":', '"reviewed": true, "reviewed":', 1),
         "the key 'reviewed' appears twice in one object"),
        ("records_beyond_frames", _now(lambda d: d["records"].extend([d["records"][0]] * 10)),
         "records holds 12 outlines, more than the 2 frames x 2 views x 2 components can hold"),
        ("poses_beyond_frames", _now(lambda d: d["poses"].extend([d["poses"][0]] * 5)),
         "poses holds 7 poses, more than the 2 frames x 2 components can hold"),
    ]


def nasty_projects() -> list[tuple[str, str]]:
    text = json.dumps(_base())
    return [(name, text) for name, text, _ in regressions()] + [
        ("nested_500", "[" * 500 + "]" * 500),
        ("nested_in_settings", _edit(lambda d: d["settings"].update(x=json.loads("[" * 200 + "]" * 200)))),
        ("huge_integer", text.replace('"schema_version": 2', '"schema_version": ' + "7" * 5000)),
        ("overflowing_float", text.replace('"distance_mm": 1200.0', '"distance_mm": 1e999', 1)),
        ("nan", text.replace("0.42", "NaN")),
        ("three_views_two_sequences", _edit(lambda d: d["views"].append(d["views"][0]))),
        ("outline_of_missing_frame", _edit(lambda d: d["records"][0].update(frame=999))),
        ("pose_of_missing_model", _edit(lambda d: d["poses"][0].update(component="patella"))),
        ("negative_density", _edit(lambda d: d["models"][0].update(point_density=-5))),
        ("huge_density", _edit(lambda d: d["models"][0].update(point_density=10**12))),
        ("string_numbers", _edit(lambda d: d["poses"][0].update(pose=["1", "2", "3", "4", "5", "6"]))),
        ("three_value_principal_point", _edit(lambda d: d["views"][0].update(principal_point_px=[1, 2, 3]))),
        ("gui_settings_list", _edit(lambda d: d["settings"].update(gui=[1, 2]))),
        ("gui_settings_true", _edit(lambda d: d["settings"].update(gui=True))),
        ("workflow_settings_text", _edit(lambda d: d["settings"].update(workflow="fast"))),
        ("truncated", text[: len(text) // 2]),
        ("binary", "\x00\x01\x02 not json"),
        ("not_an_object", "[1, 2, 3]"),
        ("unit_vector_not_unit", _edit(lambda d: d["views"][0].update(normal=[2, 0, 0]))),
        ("match_not_object", _edit(lambda d: d["poses"][0].update(match="converged"))),
        ("empty", ""),
    ]


_ODD_VALUES = [None, True, False, 0, -1, -5, 10**12, 1e300, -1e-300, 0.5, "", "12", "x" * 50, [], {}, [1, 2, 3],
               {"a": 1}, [[1, 2], [3]], "NaN"]


def mutate_document(document, rng) -> object:
    """A copy of a JSON document with one to three places replaced by an odd value, deleted,
    or duplicated (a list item repeated)."""
    import copy

    document = copy.deepcopy(document)
    for _ in range(rng.randint(1, 3)):
        places = []

        def walk(value, parent, key, places=places):
            if parent is not None:
                places.append((parent, key))
            if isinstance(value, dict):
                for k, v in value.items():
                    walk(v, value, k)
            elif isinstance(value, list):
                for i, v in enumerate(value):
                    walk(v, value, i)

        walk(document, None, None)
        if not places:
            break
        parent, key = rng.choice(places)
        action = rng.randrange(3)
        if action == 0 and isinstance(parent, dict):
            del parent[key]
        elif action == 1 and isinstance(parent, list):
            parent.insert(key, copy.deepcopy(parent[key]))
        else:
            parent[key] = copy.deepcopy(rng.choice(_ODD_VALUES))
    return document
