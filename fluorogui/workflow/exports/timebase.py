"""The time base of the timed exports: the project's frame rate (kept in
``project.settings["time"]``, see ``fluorogui.io.motion_files``), time = frame ÷ fps. The
files that need time refuse, naming the file, when there is none."""
from __future__ import annotations

from fluorogui.io.errors import InputError
from fluorogui.io.motion_files import store_frame_rate, stored_frame_rate
from fluorogui.workflow.session.events import SessionEvent
from fluorogui.workflow.session.history import Command


def frame_rate(session) -> float | None:
    """The project's frame rate (frames per second), or None when nobody gave one."""
    return stored_frame_rate(session.project.settings)


def set_frame_rate(session, fps: float | None, source: str = "user") -> None:
    """Keep the frame rate in the project (an undoable edit; None removes it)."""
    before = session.project.settings.get("time")
    probe: dict = {}
    store_frame_rate(probe, fps, source)  # checks fps before anything changes
    after = probe.get("time")

    def put(_key, value) -> None:
        if value is None:
            session.project.settings.pop("time", None)
        else:
            session.project.settings["time"] = dict(value)
        session._notify(SessionEvent.KNEE, "time")

    session.history.push(Command("Set frame rate" if fps is not None else "Remove frame rate", "time", before,
                                 after, put))


def require_frame_rate(session, path, fps: float | None = None) -> float:
    """``fps`` (an override for one export) or the project's frame rate; an InputError naming
    the file that needs it when there is neither."""
    rate = fps if fps is not None else frame_rate(session)
    if rate is None:
        raise InputError(path, "needs a frame rate (time = frame number / fps) and the project has none; "
                               "give the images' frame rate")
    return float(rate)
