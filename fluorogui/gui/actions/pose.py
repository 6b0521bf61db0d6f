"""The user's own edits of a pose: the Pose panel's spin boxes, its keyboard nudges
(declared as actions in ``gui.layout.actions``) and a drag of the model in the 3D scene,
each a mergeable undoable step of the session (``Session.set_pose``). What the panel
shows is drawn by ``SessionView``."""
from __future__ import annotations

from PySide6.QtCore import QObject

from fluorogui.gui.panels.pose_editor import PoseEditor

#: (key, axis, direction) of the keyboard nudges: Ctrl+key moves, Ctrl+Shift+key turns
NUDGE_KEYS = (("Left", 0, -1), ("Right", 0, 1), ("Down", 1, -1), ("Up", 1, 1), ("PgDown", 2, -1), ("PgUp", 2, 1))


class PoseEdits(QObject):
    """Edits of the active component's pose from the Pose panel and the 3D scene."""

    def __init__(self, controller, editor: PoseEditor, scene_widget=None) -> None:
        """``scene_widget``: the 3D scene whose model drags are edits too (None: no 3D panel)."""
        super().__init__(editor)
        self.controller = c = controller
        self.editor = editor
        editor.pose_edited.connect(
            lambda pose: c.session.set_pose(c.component, c.frame, pose, text="Edit pose", mergeable=True))
        if scene_widget is not None:
            scene_widget.pose_dragged.connect(
                lambda name, pose: c.session.set_pose(name, c.frame, pose, text="Drag model", mergeable=True))

    def nudge(self, axis: int, direction: int) -> None:
        """Step one pose value (axis 0-5: x, y, z, alpha, beta, gamma) by the panel's step."""
        self.editor.nudge(axis, direction)
