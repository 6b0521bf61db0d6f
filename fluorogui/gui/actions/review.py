"""Moving through the session and deciding on poses: next / previous / first / last
frame, the next component (K), and *Accept* / *Un-accept* as two separate actions, each
enabled only in the state where it applies (never a hidden toggle).

``ReviewActions`` is given the controller, the task runner, the matcher panel (its
Accept button) and the ``Notices``; it changes the session only through its own methods
(``Session.set_reviewed``). Its actions are declared in ``gui.layout.actions``; whether
Accept and Un-accept are enabled is declared there too, from the window's context keys
this presenter sets (``pose_acceptable``, ``pose_accepted``).
"""
from __future__ import annotations

from PySide6.QtCore import QObject

from fluorogui.core.status import Status
from fluorogui.gui.layout.specs import Context
from fluorogui.gui.notices import Notices
from fluorogui.gui.panels.matcher_panel import MatcherPanel
from fluorogui.gui.worker import TaskRunner


class ReviewActions(QObject):
    """Frame and component navigation and pose acceptance of a main window."""

    def __init__(self, controller, runner: TaskRunner, matcher: MatcherPanel, notices: Notices,
                 context: Context) -> None:
        super().__init__(notices.parent_widget)
        self.controller = controller
        self.runner = runner
        self.matcher = matcher
        self.notices = notices
        self.context = context
        matcher.accept_requested.connect(self.accept_pose)
        matcher.unaccept_requested.connect(self.unaccept_pose)
        self.runner.running_changed.connect(self._running_changed)

    def _running_changed(self, running: bool) -> None:
        """No deciding on a pose while a task may still change it (the actions say so by
        the context's "running"); at its end, what the pose now allows."""
        if not running:
            self.refresh_accept_state()

    def step_frame(self, step: int) -> None:
        self.controller.step_frame(step)

    def go_to_end(self, first: bool) -> None:
        """Show the first (Home) or the last (End) frame."""
        frames = self.controller.frames
        if frames:
            self.controller.set_frame(frames[0] if first else frames[-1])

    def cycle_component(self) -> None:
        """Make the next component active (K), wrapping round."""
        names = self.controller.components()
        if names:
            c = self.controller
            i = names.index(c.component) if c.component in names else -1
            c.set_component(names[(i + 1) % len(names)])
            self.notices.status(f"Active component: {c.component}", 4000)

    def accept_pose(self) -> bool:
        """Accept the active component's pose in this frame (flagged or not: the user has
        looked at it). Pressing it again changes nothing: Un-accept is its own action."""
        c, s = self.controller, self.controller.session
        if c.frame is None or self.runner.is_running():
            return False
        record = s.pose_record(c.component, c.frame)
        if record is None or (record.match is None and record.status == Status.PLACED):
            self.notices.status(f"Match the {c.component} component first (F5); then accept it", 8000)
            return False
        if record.reviewed:
            self.notices.status(f"The {c.component} pose in frame {c.frame} is already accepted "
                                "(Un-accept: Ctrl+Shift+Return)", 8000)
            return False
        s.set_reviewed(c.component, c.frame, True)
        self.notices.status(f"Accepted the {c.component} pose in frame {c.frame}" + (
            " although it was flagged" if record.needs_review else ""), 8000)
        return True

    def unaccept_pose(self) -> bool:
        """Take back the acceptance of the active component's pose in this frame."""
        c, s = self.controller, self.controller.session
        if c.frame is None or self.runner.is_running():
            return False
        record = s.pose_record(c.component, c.frame)
        if record is None or not record.reviewed:
            self.notices.status(f"The {c.component} pose in frame {c.frame} is not accepted", 8000)
            return False
        s.set_reviewed(c.component, c.frame, False)
        self.notices.status(f"Un-accepted the {c.component} pose in frame {c.frame}", 8000)
        return True

    def refresh_accept_state(self) -> None:
        """Accept and Un-accept enabled for the state the active pose is in."""
        c, s = self.controller, self.controller.session
        record = s.pose_record(c.component, c.frame) if c.frame is not None else None
        can = record is not None and not (record.match is None and record.status == Status.PLACED)
        accepted = bool(record is not None and record.reviewed)
        self.context.set(pose_acceptable=can, pose_accepted=accepted)
        self.matcher.set_accepted(accepted if can or accepted else None)
