"""The anatomical frame of a component as a 4×4 matrix (anatomical → model), edited in a
table, reset to the default the mesh gives, and checked (``check_frame``) before OK."""
from __future__ import annotations

import numpy as np
from PySide6.QtWidgets import (
    QDialog,
    QDialogButtonBox,
    QLabel,
    QPushButton,
    QTableWidget,
    QTableWidgetItem,
    QVBoxLayout,
    QWidget,
)

from fluorogui.core.knee.kinematics import KinematicsError, check_frame


class AnatomicalFrameDialog(QDialog):
    """A component's anatomical frame as a 4×4 (anatomical → model), checked on OK."""

    def __init__(self, component: str, matrix, default, source: str, parent: QWidget | None = None) -> None:
        super().__init__(parent)
        self.setWindowTitle(f"Anatomical frame of the {component} component")
        self.default = np.asarray(default, dtype=float)
        self.result_matrix: np.ndarray | None = None
        self.reset_requested = False
        note = QLabel(f"Anatomical → model coordinates ({source}). Columns: x to the subject's right, "
                      "y anterior, z proximal, and the origin (mm) at the joint centre.")
        note.setWordWrap(True)
        self.table = QTableWidget(4, 4)
        self.table.setHorizontalHeaderLabels(["x", "y", "z", "origin"])
        self.set_matrix(matrix)
        self.error = QLabel("")
        self.error.setObjectName("error")
        self.error.setWordWrap(True)
        reset = QPushButton("Default from the mesh")
        reset.clicked.connect(self._reset)
        buttons = QDialogButtonBox(QDialogButtonBox.StandardButton.Ok | QDialogButtonBox.StandardButton.Cancel)
        buttons.addButton(reset, QDialogButtonBox.ButtonRole.ResetRole)
        buttons.accepted.connect(self._accept)
        buttons.rejected.connect(self.reject)
        layout = QVBoxLayout(self)
        layout.addWidget(note)
        layout.addWidget(self.table)
        layout.addWidget(self.error)
        layout.addWidget(buttons)

    def set_matrix(self, matrix) -> None:
        matrix = np.asarray(matrix, dtype=float)
        for r in range(4):
            for c in range(4):
                self.table.setItem(r, c, QTableWidgetItem(f"{matrix[r, c]:.9f}"))

    def matrix(self) -> np.ndarray:
        values = np.full((4, 4), np.nan)
        for r in range(4):
            for c in range(4):
                item = self.table.item(r, c)
                try:
                    values[r, c] = float(item.text()) if item is not None else np.nan
                except ValueError:
                    pass
        return values

    def _reset(self) -> None:
        self.reset_requested = True
        self.set_matrix(self.default)

    def _accept(self) -> None:
        try:
            self.result_matrix = check_frame(self.matrix())
        except KinematicsError as exc:
            self.error.setText(f"Not a valid frame: {exc}.")
            return
        self.accept()
