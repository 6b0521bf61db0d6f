"""The export dialog: which results to write (poses, kinematics, Autoscoper .tra, JointTrack
.jts, the kinematics figure; C3D, OpenSim .mot and .trc, XMALab rigid-body CSV), under
which names in which folder, for JointTrack in which view's camera frame, the project's
frame rate (time = frame ÷ fps, which C3D, .trc and .mot need) and whether poses not yet
matched or accepted go in. It only asks; ``actions.knee`` writes through the workflow."""
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

EXPORT_KINDS = (  # key, label, default file name
    ("poses", "Poses, residuals, status and kinematics (CSV)", "{stem}_poses.csv"),
    ("kinematics", "Kinematics (CSV)", "{stem}_kinematics.csv"),
    ("tra", "Autoscoper poses (.tra)", "{stem}.tra"),
    ("jts", "JointTrack poses (femoral.jts, tibial.jts)", "{stem}_jointtrack"),
    ("plot", "Kinematics figure (PNG)", "{stem}_kinematics.png"),
    ("c3d", "Anatomical markers (C3D)", "{stem}.c3d"),
    ("trc", "Anatomical markers for OpenSim (.trc)", "{stem}.trc"),
    ("mot", "Kinematics for OpenSim (.mot)", "{stem}_knee.mot"),
    ("xromm", "XMALab rigid-body transformations (CSV)", "{stem}_xromm.csv"),
)
#: the exports that need the frame rate
TIMED_KINDS = ("c3d", "trc", "mot")


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
        self.frame_rate = QDoubleSpinBox()
        self.frame_rate.setObjectName("export_fps")
        self.frame_rate.setRange(0.0, MAX_FPS)
        self.frame_rate.setDecimals(3)
        self.frame_rate.setSuffix(" frames/s")
        self.frame_rate.setSpecialValueText("not known")
        self.frame_rate.setValue(fps or 0.0)
        self.frame_rate.setToolTip("The images' frame rate: time = frame number / frame rate. C3D, .trc and .mot "
                                   "need it; it is kept in the project.")
        form.addRow("Frame rate", self.frame_rate)
        self.include_unreviewed = QCheckBox("Also poses not matched or accepted (placed, or flagged for review)")
        self.include_unreviewed.setObjectName("export_include_unreviewed")
        self.include_unreviewed.setToolTip(".tra, .jts, C3D, .trc, .mot and XMALab files carry no status: by default "
                                           "such poses are left out (NaN, invalid markers)")
        form.addRow("", self.include_unreviewed)
        self.time_note = QLabel("")
        self.time_note.setObjectName("export_time_note")
        self.time_note.setWordWrap(True)
        form.addRow("", self.time_note)
        for key in TIMED_KINDS:
            self.checks[key].toggled.connect(lambda _on: self._explain_time())
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
        timed = [k for k in TIMED_KINDS if self.checks[k].isChecked()]
        needs = bool(timed) and self.fps() is None
        self.time_note.setText("C3D, .trc and .mot need the frame rate: give it above." if needs else "")
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
