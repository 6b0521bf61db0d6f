"""Hand-made nasty project files (built from the small valid fixture, so the corpus stays a
few kilobytes): each is a name and the file's text. Every one must be refused with one
InputError naming the file, by the loader and by the app's open path."""
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


def nasty_projects() -> list[tuple[str, str]]:
    text = json.dumps(_base())
    return [
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
