"""The export dialog: which results to write (one check box per format of the export
registry, ``fluorogui.workflow.exports``), under which names in which folder, for the
formats written in one view's camera frame (JointTrack) which view, the project's frame
rate (time = frame ÷ fps, which the timed formats need) and whether poses not yet matched
or accepted go in. It only asks; ``actions.knee`` writes through the workflow."""
from __future__ import annotations

from pathlib import Path

from PySide6.QtWidgets import (
    QCheckBox,
    QComboBox,
    QDialog,
    QDialogButtonBox,
    QDoubleSpinBox,
    QFileDialog,
    QFormLayout,
    QHBoxLayout,
    QLabel,
    QLineEdit,
    QPushButton,
    QVBoxLayout,
    QWidget,
)

from fluorogui.io.motion_files import MAX_FPS
from fluorogui.workflow.exports.registry import formats


def _words(names: list[str]) -> str:
    return names[0] if len(names) == 1 else ", ".join(names[:-1]) + " and " + names[-1]

class ExportDialog(QDialog):
    """Which results to write, where, and (for JointTrack) in which view's camera frame."""

    def __init__(self, folder: Path, stem: str, views: int, parent: QWidget | None = None,
                 fps: float | None = None) -> None:
        super().__init__(parent)
        self.setWindowTitle("Export results")
        self.checks: dict[str, QCheckBox] = {}
        self.names: dict[str, QLineEdit] = {}
        form = QFormLayout()
        self.folder = QLineEdit(str(folder))
        self.folder.setObjectName("export_folder")
        browse = QPushButton("Browse…")
        browse.clicked.connect(self._browse)
        row = QHBoxLayout()
        row.addWidget(self.folder, 1)
        row.addWidget(browse)
        form.addRow("Folder", row)
        for fmt in formats():  # one row per registered format
            check = QCheckBox(fmt.label)
            check.setChecked(fmt.checked)
            name = QLineEdit(fmt.default_name.format(stem=stem))
            name.setObjectName(f"export_{fmt.name}")
            self.checks[fmt.name], self.names[fmt.name] = check, name
            form.addRow(check, name)
        self.timed = [f for f in formats() if f.timed]
        self.view = QComboBox()
        for k in range(views):
            self.view.addItem(f"View {k + 1}", k)
        with_view = [f.view_label for f in formats() if f.needs_view]
        form.addRow(" / ".join(with_view) or "Camera", self.view)
        self.frame_rate = QDoubleSpinBox()
        self.frame_rate.setObjectName("export_fps")
        self.frame_rate.setRange(0.0, MAX_FPS)
        self.frame_rate.setDecimals(3)
        self.frame_rate.setSuffix(" frames/s")
        self.frame_rate.setSpecialValueText("not known")
        self.frame_rate.setValue(fps or 0.0)
        self.frame_rate.setToolTip(f"The images' frame rate: time = frame number / frame rate. "
                                   f"{_words([f.short for f in self.timed])} need it; it is kept in the project.")
        form.addRow("Frame rate", self.frame_rate)
        self.include_unreviewed = QCheckBox("Also poses not matched or accepted (placed, or flagged for review)")
        self.include_unreviewed.setObjectName("export_include_unreviewed")
        without_status = [f.short for f in formats() if f.statusless or f.motion]
        self.include_unreviewed.setToolTip(f"{_words(without_status)} files carry no status: by default such poses "
                                           "are left out (NaN, invalid markers)")
        form.addRow("", self.include_unreviewed)
        self.time_note = QLabel("")
        self.time_note.setObjectName("export_time_note")
        self.time_note.setWordWrap(True)
        form.addRow("", self.time_note)
        for fmt in self.timed:
            self.checks[fmt.name].toggled.connect(lambda _on: self._explain_time())
        self.frame_rate.valueChanged.connect(lambda _v: self._explain_time())
        self._explain_time()
        buttons = QDialogButtonBox(QDialogButtonBox.StandardButton.Ok | QDialogButtonBox.StandardButton.Cancel)
        buttons.button(QDialogButtonBox.StandardButton.Ok).setText("Export")
        buttons.accepted.connect(self.accept)
        buttons.rejected.connect(self.reject)
        layout = QVBoxLayout(self)
        layout.addLayout(form)
        layout.addWidget(buttons)

    def _explain_time(self) -> None:
        timed = [f for f in self.timed if self.checks[f.name].isChecked()]
        needs = bool(timed) and self.fps() is None
        self.time_note.setText(f"{_words([f.short for f in self.timed])} need the frame rate: give it above."
                               if needs else "")
        self.time_note.setVisible(needs)

    def _browse(self) -> None:
        folder = QFileDialog.getExistingDirectory(self, "Export to folder", self.folder.text())
        if folder:
            self.folder.setText(folder)

    def fps(self) -> float | None:
        """The frame rate given (None when not known)."""
        value = float(self.frame_rate.value())
        return value if value > 0 else None

    def targets(self) -> dict[str, Path]:
        folder = Path(self.folder.text())
        return {k: folder / self.names[k].text() for k, check in self.checks.items() if check.isChecked()}
