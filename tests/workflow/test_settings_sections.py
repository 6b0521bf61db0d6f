"""The sections of a project's settings are registered once (``core.settings``): every key
the workflow, io and the simulations write is there with its owner, the workflow's
records are the registered ``workflow.`` sections, and a project saved with them loads."""
from __future__ import annotations

import json
from dataclasses import fields

import pytest

from fluorogui.core.settings import SECTIONS, Section, TrackingSettings, check_sections, register
from fluorogui.io import motion_files
from fluorogui.io.motion_files import store_frame_rate
from fluorogui.workflow import Session, WorkflowSettings
from fluorogui.workflow import settings as workflow_settings
from fluorogui.workflow.session import knee, work


@pytest.mark.parametrize("key, module", [
    (workflow_settings.SETTINGS_KEY, workflow_settings), (knee.KNEE_KEY, knee), (work.RIM_KEY, work),
    (motion_files.TIME_KEY, motion_files)])
def test_every_key_the_code_writes_is_registered_with_its_owner(key, module):
    assert SECTIONS[key].owner == module.__name__


def test_the_workflow_settings_are_the_registered_workflow_sections():
    registered = {k.split(".", 1)[1]: s.record for k, s in SECTIONS.items() if k.startswith("workflow.")}
    assert {f.name: f.type for f in fields(WorkflowSettings)} == {k: r.__name__ for k, r in registered.items()}
    assert WorkflowSettings.from_dict(None).tracking == SECTIONS["workflow.tracking"].default() == TrackingSettings()


def test_a_demo_session_holds_only_registered_sections_and_they_pass(demo):
    session = Session.open(demo)
    session.set_side("left")
    session.set_settings(WorkflowSettings())
    store_frame_rate(session.project.settings, 25.0, "user")
    session.match(1, "femoral")
    settings = json.loads(json.dumps(session.project.settings))
    assert {"workflow", "kinematics", "time", "rim_models", "demo", "demo_truth"} <= set(settings) <= set(SECTIONS)
    check_sections(settings)


def test_a_section_of_the_wrong_kind_is_named_and_one_registered_twice_refused():
    with pytest.raises(ValueError, match=r"field 'settings.workflow.tracking.typical_window' must be a whole"):
        check_sections({"workflow": {"tracking": {"typical_window": 2.5}}})
    with pytest.raises(ValueError, match="field 'settings.workflow.tracking' must be an object, not None"):
        check_sections({"workflow": {"tracking": None}})
    check_sections({"kinematics": "damaged", "time": [], "rim_models": 3})  # read leniently by their owners
    with pytest.raises(ValueError, match="registered twice"):
        register(Section("time", "elsewhere"))
