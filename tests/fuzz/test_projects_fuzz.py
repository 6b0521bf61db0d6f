"""Fuzzing the project loader: hand-made nasty files and Hypothesis mutations of a valid
project. Whatever the file holds, ``load_project`` either gives a project that saves and
reopens unchanged, or raises one InputError whose single line names the file."""
from __future__ import annotations

import copy
import json
from pathlib import Path

import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st
from nasty_projects import FIXTURE, nasty_projects, regressions

from fluorogui.io.errors import InputError
from fluorogui.io.project.document import load_project, save_project

JSON_LEAVES = st.one_of(st.none(), st.booleans(), st.integers(-10**40, 10**40),
                        st.floats(allow_nan=False, allow_infinity=False), st.text(max_size=8))
JSON_VALUES = st.recursive(JSON_LEAVES, lambda inner: st.lists(inner, max_size=4) |
                           st.dictionaries(st.text(max_size=6), inner, max_size=4), max_leaves=12)


def outcome(path: Path) -> str:
    """'accepted' (after a save / reopen round trip) or 'refused'; anything else fails."""
    try:
        project = load_project(path)
    except InputError as exc:
        message = str(exc)
        assert message.startswith(f"{path}: ") and "\n" not in message, message
        return "refused"
    again = path.with_name("again.fluoro")
    save_project(project, again)
    assert load_project(again) == project
    return "accepted"


@pytest.mark.parametrize("name, text", nasty_projects(), ids=[n for n, _ in nasty_projects()])
def test_nasty_projects_are_refused(tmp_path, name, text):
    path = tmp_path / f"{name}.fluoro"
    path.write_text(text, encoding="utf-8")
    assert outcome(path) == "refused"


@pytest.mark.parametrize("name, text, words", regressions(), ids=[n for n, _, _ in regressions()])
def test_projects_contradicting_themselves_are_refused_naming_the_field(tmp_path, name, text, words):
    """The issue's regression cases: each loaded before, the contradiction kept."""
    path = tmp_path / "p.fluoro"
    path.write_text(text, encoding="utf-8")
    with pytest.raises(InputError) as info:
        load_project(path)
    assert str(info.value).startswith(f"{path}: {words}"), str(info.value)
    assert "\n" not in str(info.value)


def _paths(value, prefix=()):
    """Every (path, value) inside a JSON document."""
    yield prefix, value
    if isinstance(value, dict):
        for k, v in value.items():
            yield from _paths(v, prefix + (k,))
    elif isinstance(value, list):
        for i, v in enumerate(value):
            yield from _paths(v, prefix + (i,))


BASE = json.loads(FIXTURE.read_text())
PLACES = [p for p, _ in _paths(BASE) if p]


@st.composite
def mutated(draw):
    document = copy.deepcopy(BASE)
    for _ in range(draw(st.integers(1, 3))):
        place = draw(st.sampled_from(PLACES))
        parent = document
        try:
            for key in place[:-1]:
                parent = parent[key]
            if draw(st.booleans()) and isinstance(parent, dict):
                parent.pop(place[-1], None)
            else:
                parent[place[-1]] = draw(JSON_VALUES)
        except (KeyError, IndexError, TypeError):
            continue  # an earlier mutation removed the place
    return document


@settings(max_examples=60, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture])
@given(document=mutated())
def test_mutated_projects_load_or_are_refused(tmp_path, document):
    path = tmp_path / "p.fluoro"
    path.write_text(json.dumps(document))
    assert outcome(path) in ("accepted", "refused")


@settings(max_examples=40, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture])
@given(data=st.binary(max_size=300))
def test_random_bytes_are_refused(tmp_path, data):
    path = tmp_path / "p.fluoro"
    path.write_bytes(data)
    assert outcome(path) == "refused"
