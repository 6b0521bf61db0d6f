"""Moving through the session and deciding on poses: next / previous / first / last
frame, the next component (K), and *Accept* / *Un-accept* as two separate actions, each
enabled only in the state where it applies (never a hidden toggle).

``ReviewActions`` belongs to a main window; it changes the session only through its own
methods (``Session.set_reviewed``).
"""
from __future__ import annotations

from PySide6.QtCore import QObject

from fluorogui.core.status import Status


class ReviewActions(QObject):
    """Frame and component navigation and pose acceptance of a main window."""

    def __init__(self, window) -> None:
        super().__init__(window)
        self.window = window
        self.controller = window.controller
        self.runner = window.runner
        add = window.add_action
        self.accept_action = add("&Accept pose", self.accept_pose, "Ctrl+Return", "accept",
                                 "Accept the active component's pose in this frame (Ctrl+Return)")
        self.unaccept_action = add("&Un-accept pose", self.unaccept_pose, "Ctrl+Shift+Return",
                                   tip="Take back the acceptance of the active component's pose (Ctrl+Shift+Return)")
        self.next_action = add("&Next frame", lambda: self.step_frame(1), "PgDown")
        self.prev_action = add("&Previous frame", lambda: self.step_frame(-1), "PgUp")
        self.first_action = add("&First frame", lambda: self.go_to_end(first=True), "Home")
        self.last_action = add("&Last frame", lambda: self.go_to_end(first=False), "End")
        self.next_component_action = add("Next &component", self.cycle_component, "K",
                                         tip="Make the next component the active one (K)")
        window.matcher.accept_requested.connect(self.accept_pose)
        window.matcher.unaccept_requested.connect(self.unaccept_pose)
        self.runner.running_changed.connect(self._running_changed)

    def _running_changed(self, running: bool) -> None:
        """No deciding on a pose while a task may still change it."""
        for action in (self.accept_action, self.unaccept_action):
            action.setEnabled(not running)
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
            self.window.statusBar().showMessage(f"Active component: {c.component}", 4000)

    def accept_pose(self) -> bool:
        """Accept the active component's pose in this frame (flagged or not: the user has
        looked at it). Pressing it again changes nothing: Un-accept is its own action."""
        c, s = self.controller, self.controller.session
        if c.frame is None or self.runner.is_running():
            return False
        record = s.pose_record(c.component, c.frame)
        if record is None or (record.match is None and record.status == Status.PLACED):
            self.window.statusBar().showMessage(f"Match the {c.component} component first (F5); then accept it", 8000)
            return False
        if record.reviewed:
            self.window.statusBar().showMessage(f"The {c.component} pose in frame {c.frame} is already accepted "
                                         "(Un-accept: Ctrl+Shift+Return)", 8000)
            return False
        s.set_reviewed(c.component, c.frame, True)
        self.window.statusBar().showMessage(f"Accepted the {c.component} pose in frame {c.frame}" + (
            " although it was flagged" if record.needs_review else ""), 8000)
        return True

    def unaccept_pose(self) -> bool:
        """Take back the acceptance of the active component's pose in this frame."""
        c, s = self.controller, self.controller.session
        if c.frame is None or self.runner.is_running():
            return False
        record = s.pose_record(c.component, c.frame)
        if record is None or not record.reviewed:
            self.window.statusBar().showMessage(f"The {c.component} pose in frame {c.frame} is not accepted", 8000)
            return False
        s.set_reviewed(c.component, c.frame, False)
        self.window.statusBar().showMessage(f"Un-accepted the {c.component} pose in frame {c.frame}", 8000)
        return True

    def refresh_accept_state(self) -> None:
        """Accept and Un-accept enabled for the state the active pose is in."""
        c, s = self.controller, self.controller.session
        record = s.pose_record(c.component, c.frame) if c.frame is not None else None
        can = record is not None and not (record.match is None and record.status == Status.PLACED)
        accepted = bool(record is not None and record.reviewed)
        self.accept_action.setEnabled(can and not accepted)
        self.unaccept_action.setEnabled(accepted)
        self.window.matcher.set_accepted(accepted if can or accepted else None)
