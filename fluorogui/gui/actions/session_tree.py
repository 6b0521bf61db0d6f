"""The Session panel's presenter: a tree of the session's views, components and frames,
rebuilt when another project is put on screen; activating a component or a frame there
makes it the active component or the frame on screen."""
from __future__ import annotations

from PySide6.QtCore import QObject, Qt
from PySide6.QtWidgets import QTreeWidget, QTreeWidgetItem

#: the most frames listed (a long sequence is stepped through in the Frames panel)
MAX_FRAMES_LISTED = 500


class SessionTree(QObject):
    """A ``QTreeWidget`` showing the session."""

    def __init__(self, controller, tree: QTreeWidget) -> None:
        super().__init__(tree)
        self.controller = controller
        self.tree = tree
        tree.itemActivated.connect(self._activated)
        tree.itemClicked.connect(self._activated)
        controller.project_replaced.connect(self.refresh)

    def refresh(self) -> None:
        s = self.controller.session
        self.tree.clear()
        root = QTreeWidgetItem([s.path.name if s.path else "Untitled session"])
        views = QTreeWidgetItem(root, ["Views"])
        for i, v in enumerate(s.views):
            QTreeWidgetItem(views, [f"View {i + 1}: {v.name or 'calibrated'} ({v.image_size[0]}×{v.image_size[1]})"])
        models = QTreeWidgetItem(root, ["Components"])
        for name in s.components():
            item = QTreeWidgetItem(models, [f"{name}  ({s.project.model(name).mesh_path.name})"])
            item.setData(0, Qt.ItemDataRole.UserRole, ("component", name))
        frames = QTreeWidgetItem(root, [f"Frames ({len(s.frames)})"])
        for f in s.frames[:MAX_FRAMES_LISTED]:
            item = QTreeWidgetItem(frames, [f"Frame {f}"])
            item.setData(0, Qt.ItemDataRole.UserRole, ("frame", f))
        self.tree.addTopLevelItem(root)
        root.setExpanded(True)
        views.setExpanded(True)
        models.setExpanded(True)

    def _activated(self, item, _column=0) -> None:
        data = item.data(0, Qt.ItemDataRole.UserRole)
        if not data:
            return
        kind, value = data
        if kind == "component":
            self.controller.set_component(value)
        elif kind == "frame":
            self.controller.set_frame(value)
