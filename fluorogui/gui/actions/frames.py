"""The Frames panel's presenter: the timeline shows every frame of the session with its
state (and, in its tooltip, why a frame needs review) and frames the one on screen; a
click or an arrow key there puts another frame on screen."""
from __future__ import annotations

from PySide6.QtCore import QObject

from fluorogui.gui.panels.matcher_panel import describe_pose
from fluorogui.gui.panels.timeline import Timeline
from fluorogui.workflow.session import FrameState


class FramesPresenter(QObject):
    """A ``Timeline`` kept in step with the session."""

    def __init__(self, controller, timeline: Timeline) -> None:
        super().__init__(timeline)
        self.controller = c = controller
        self.timeline = timeline
        timeline.frame_selected.connect(c.set_frame)
        c.project_replaced.connect(self._project_replaced)
        c.frame_changed.connect(timeline.set_current)
        c.pose_changed.connect(lambda frame, _component: self._frame_state_changed(frame))
        c.outline_changed.connect(lambda key, _component: self._frame_state_changed(key[0]))

    def _project_replaced(self) -> None:
        s = self.controller.session
        self.timeline.set_frames(s.frames, s.frame_states())
        for frame in s.frames:
            self.timeline.set_note(frame, self._frame_note(frame))

    def _frame_note(self, frame: int) -> str:
        """Why a frame needs review, for the timeline's tooltip ("" when it does not)."""
        s = self.controller.session
        notes = []
        for name in s.components():
            record = s.pose_record(name, frame)
            if record is not None and record.needs_review:
                notes.append(describe_pose(name, record)[0])
        return "\n".join(notes)

    def _frame_state_changed(self, frame: int) -> None:
        state = self.controller.session.frame_state(frame)
        self.timeline.set_state(frame, state)
        self.timeline.set_note(frame, self._frame_note(frame) if state == FrameState.NEEDS_REVIEW else "")
