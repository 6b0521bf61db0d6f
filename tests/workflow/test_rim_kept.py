"""The images' rim models are judged once per project: kept in the project after the first
matched frames, and a later run (or a reopened project) starts from them without fitting."""
import pytest

import fluorogui.core.matching.loop as loop
from fluorogui.workflow import Session


@pytest.mark.slow
def test_rim_models_are_kept_in_the_project_and_not_fitted_again(demo, monkeypatch):
    session = Session.open(demo)
    session.project.settings.pop("rim_models", None)  # the demo's frame 0 was matched: forget its judgement
    assert session.rim_models() == {}
    list(session.track(first=1, last=3))
    kept = session.rim_models()
    assert set(kept) == {"femoral", "tibial"} and all(len(models) == 2 for models in kept.values())
    session.save()
    fitted = []
    real = loop.soft_edge_views
    monkeypatch.setattr(loop, "soft_edge_views", lambda *a, **k: fitted.append(1) or real(*a, **k))
    again = Session.open(demo)
    assert again.rim_models() == kept  # through the project file
    results = list(again.track(first=1, last=3, redo=True))
    assert fitted == [] and all(r.status == "matched" for r in results)
