"""The export dialog: which results to write (poses, kinematics, Autoscoper .tra, JointTrack
.jts, the kinematics figure), under which names in which folder, and for JointTrack in
which view's camera frame. It only asks; ``actions.knee`` writes through the workflow."""
from __future__ import annotations

from pathlib import Path

from PySide6.QtWidgets import (
    QCheckBox,
    QComboBox,
    QDialog,
    QDialogButtonBox,
    QFileDialog,
    QFormLayout,
    QHBoxLayout,
    QLineEdit,
    QPushButton,
    QVBoxLayout,
    QWidget,
)

EXPORT_KINDS = (  # key, label, default file name
    ("poses", "Poses, residuals, status and kinematics (CSV)", "{stem}_poses.csv"),
    ("kinematics", "Kinematics (CSV)", "{stem}_kinematics.csv"),
    ("tra", "Autoscoper poses (.tra)", "{stem}.tra"),
    ("jts", "JointTrack poses (femoral.jts, tibial.jts)", "{stem}_jointtrack"),
    ("plot", "Kinematics figure (PNG)", "{stem}_kinematics.png"),
)


class ExportDialog(QDialog):
    """Which results to write, where, and (for JointTrack) in which view's camera frame."""

    def __init__(self, folder: Path, stem: str, views: int, parent: QWidget | None = None) -> None:
        super().__init__(parent)
        self.setWindowTitle("Export results")
        self.checks: dict[str, QCheckBox] = {}
        self.names: dict[str, QLineEdit] = {}
        form = QFormLayout()
        self.folder = QLineEdit(str(folder))
        browse = QPushButton("Browse…")
        browse.clicked.connect(self._browse)
        row = QHBoxLayout()
        row.addWidget(self.folder, 1)
        row.addWidget(browse)
        form.addRow("Folder", row)
        for key, label, pattern in EXPORT_KINDS:
            check = QCheckBox(label)
            check.setChecked(key in ("poses", "kinematics"))
            name = QLineEdit(pattern.format(stem=stem))
            name.setObjectName(f"export_{key}")
            self.checks[key], self.names[key] = check, name
            form.addRow(check, name)
        self.view = QComboBox()
        for k in range(views):
            self.view.addItem(f"View {k + 1}", k)
        form.addRow("JointTrack camera", self.view)
        buttons = QDialogButtonBox(QDialogButtonBox.StandardButton.Ok | QDialogButtonBox.StandardButton.Cancel)
        buttons.button(QDialogButtonBox.StandardButton.Ok).setText("Export")
        buttons.accepted.connect(self.accept)
        buttons.rejected.connect(self.reject)
        layout = QVBoxLayout(self)
        layout.addLayout(form)
        layout.addWidget(buttons)

    def _browse(self) -> None:
        folder = QFileDialog.getExistingDirectory(self, "Export to folder", self.folder.text())
        if folder:
            self.folder.setText(folder)

    def targets(self) -> dict[str, Path]:
        folder = Path(self.folder.text())
        return {k: folder / self.names[k].text() for k, check in self.checks.items() if check.isChecked()}
