"""The calibration wizard: plate images -> holes and residual map -> accept; bead images ->
detected beads and reprojection errors -> accept; the views are written to a folder.

Presentation only: the fits are ``fluorogui.core.calibration.distortion.fit_plate`` and
``fluorogui.core.calibration.beads.calibrate_view``, run off the GUI thread by ``TaskRunner``; the
tasks read files and return plain results, the pages show them. On finish
``self.views`` holds the calibrated views (each carrying its distortion correction) and
the folder gets ``view<k>_mayacam2.txt`` (geometry, for XMALab / Autoscoper) and
``view<k>.json`` (geometry and correction, for fluorogui).
"""
from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import cv2
import numpy as np
from PySide6.QtCore import Qt
from PySide6.QtGui import QImage, QPixmap
from PySide6.QtWidgets import (
    QComboBox,
    QDoubleSpinBox,
    QFileDialog,
    QFormLayout,
    QGridLayout,
    QHBoxLayout,
    QLabel,
    QLineEdit,
    QPushButton,
    QToolButton,
    QVBoxLayout,
    QWidget,
    QWizard,
    QWizardPage,
)

from fluorogui.gui.worker import TaskRunner

PICTURE_PX = 240
N_VIEWS = 2


# -- tasks (no widgets) ---------------------------------------------------------------------------
@dataclass
class PlateOutcome:
    view: int
    summary: dict
    correction: dict
    picture: np.ndarray


@dataclass
class BeadOutcome:
    view: int
    calibration: object  # fluorogui.core.calibration.beads.BeadCalibration
    picture: np.ndarray


def plate_task(plates: dict[int, str], spacing_mm: float, grid: str, model: str):
    """Fit a correction for every view that has a plate image (``workflow.calibration``)."""
    def task(reporter) -> list[PlateOutcome]:
        from fluorogui.core.calibration.distortion import residual_picture
        from fluorogui.workflow.calibration import fit_plates

        fits = fit_plates(plates, spacing_mm, grid=grid, model=model, progress=lambda text: reporter.report(text,
                                                                                                            force=True),
                          cancel=reporter.cancelled)
        return [PlateOutcome(view, r.fit.summary(), r.correction, residual_picture(r.image, r.fit))
                for view, r in sorted(fits.items())]
    return task


def bead_task(images: dict[int, str], phantom_csv: str, corrections: dict[int, dict], pitch: float | None):
    """Calibrate every view that has a bead image, each corrected with its plate fit first
    (``workflow.calibration``)."""
    def task(reporter) -> list[BeadOutcome]:
        from fluorogui.core.calibration.distortion import correction_from_dict
        from fluorogui.io.beads import read_phantom_csv
        from fluorogui.workflow.calibration import calibrate_views

        found = calibrate_views(images, phantom_csv, corrections=corrections, pitch=pitch,
                                progress=lambda text: reporter.report(text, force=True), cancel=reporter.cancelled)
        beads = read_phantom_csv(phantom_csv)
        out = []
        for view, r in sorted(found.items()):
            correction = correction_from_dict(corrections[view]) if view in corrections else None
            out.append(BeadOutcome(view, r.calibration, _bead_picture(r.image, r.calibration, beads, correction)))
        return out
    return task


def _bead_picture(image, result, beads, correction) -> np.ndarray:
    """The bead image with each matched bead circled (green) and its reprojection (red cross)."""
    gray = cv2.normalize(np.asarray(image, np.float32), None, 0, 255, cv2.NORM_MINMAX).astype(np.uint8)
    out = cv2.cvtColor(gray, cv2.COLOR_GRAY2RGB)
    projected = result.view.project(beads[[i for i, _ in result.pairs]])
    if correction is not None:
        projected = correction.distort_points(projected)  # back into the recorded image
    for (u, v) in projected:
        p = (int(round(u)), int(round(v)))
        cv2.drawMarker(out, p, (230, 40, 40), cv2.MARKER_CROSS, 9, 1)
        cv2.circle(out, p, 7, (40, 200, 40), 1, cv2.LINE_AA)
    return out


def _pixmap(rgb: np.ndarray) -> QPixmap:
    rgb = np.ascontiguousarray(rgb)
    image = QImage(rgb.data, rgb.shape[1], rgb.shape[0], rgb.strides[0], QImage.Format.Format_RGB888)
    return QPixmap.fromImage(image.copy()).scaled(PICTURE_PX, PICTURE_PX, Qt.AspectRatioMode.KeepAspectRatio,
                                                   Qt.TransformationMode.SmoothTransformation)


def _path_row(edit: QLineEdit, title: str, name_filter: str, folder: bool = False) -> QWidget:
    button = QToolButton()
    button.setText("Browse…")

    def choose():
        if folder:
            path = QFileDialog.getExistingDirectory(edit, title, edit.text())
        else:
            path, _ = QFileDialog.getOpenFileName(edit, title, edit.text(), name_filter)
        if path:
            edit.setText(path)

    button.clicked.connect(choose)
    row = QHBoxLayout()
    row.setContentsMargins(0, 0, 0, 0)
    row.addWidget(edit, 1)
    row.addWidget(button)
    holder = QWidget()
    holder.setLayout(row)
    return holder


class _FitPage(QWizardPage):
    """A page with per-view inputs, a Run button, pictures and a status line."""

    def __init__(self, title: str, subtitle: str, run_text: str) -> None:
        super().__init__()
        self.setTitle(title)
        self.setSubTitle(subtitle)
        self.runner = TaskRunner(self)
        self.form = QFormLayout()
        self.run_button = QPushButton(run_text)
        self.status = QLabel()
        self.status.setWordWrap(True)
        self.status.setTextInteractionFlags(Qt.TextInteractionFlag.TextSelectableByMouse)
        self.pictures = [QLabel() for _ in range(N_VIEWS)]
        self.texts = [QLabel() for _ in range(N_VIEWS)]
        grid = QGridLayout()
        for k in range(N_VIEWS):
            self.pictures[k].setFixedSize(PICTURE_PX, PICTURE_PX)
            self.pictures[k].setAlignment(Qt.AlignmentFlag.AlignCenter)
            self.pictures[k].setStyleSheet("background: #202020; color: #909090;")
            self.pictures[k].setText(f"view {k + 1}")
            self.texts[k].setWordWrap(True)
            grid.addWidget(self.pictures[k], 0, k)
            grid.addWidget(self.texts[k], 1, k)
        layout = QVBoxLayout(self)
        layout.addLayout(self.form)
        layout.addWidget(self.run_button, 0, Qt.AlignmentFlag.AlignLeft)
        layout.addWidget(self.status)
        layout.addLayout(grid)
        self.runner.progress.connect(lambda text: self.status.setText(str(text)))
        self.runner.failed.connect(self._failed)
        self.runner.running_changed.connect(lambda running: self.run_button.setEnabled(not running))

    def _failed(self, message: str) -> None:
        self.status.setText(f"<span style='color:#c62828'>{message}</span>")
        self.completeChanged.emit()


class PlatePage(_FitPage):
    def __init__(self) -> None:
        super().__init__("Distortion correction", "Perforated-plate image of each view (leave empty to skip a "
                         "view). Holes are detected, the ideal grid fitted, and the residual shown per hole "
                         "(vectors 20x; green < 0.1 px, yellow < 0.5 px, red above).", "Detect holes and fit")
        self.plates = [QLineEdit() for _ in range(N_VIEWS)]
        for k, edit in enumerate(self.plates):
            edit.setObjectName(f"plate{k + 1}")
            self.form.addRow(f"Plate image, view {k + 1}:", _path_row(edit, "Plate image", "Images (*)"))
        self.spacing = QDoubleSpinBox()
        self.spacing.setRange(0.1, 100.0)
        self.spacing.setDecimals(3)
        self.spacing.setValue(5.0)
        self.spacing.setSuffix(" mm")
        self.grid = QComboBox()
        self.grid.addItems(["square", "hex"])
        self.model = QComboBox()
        self.model.addItems(["global", "local"])
        self.model.setToolTip("global: Gronenschild's polynomial; local: XMALab-like local weighted mean")
        self.form.addRow("Hole spacing:", self.spacing)
        self.form.addRow("Grid:", self.grid)
        self.form.addRow("Model:", self.model)
        self.corrections: dict[int, dict] = {}
        self.run_button.clicked.connect(self.run)
        self.runner.finished.connect(self._show)

    def run(self) -> None:
        plates = {k: e.text().strip() for k, e in enumerate(self.plates) if e.text().strip()}
        self.corrections = {}
        if not plates:
            self.status.setText("No plate images: the views will not be corrected.")
            self.completeChanged.emit()
            return
        self.runner.start(plate_task(plates, self.spacing.value(), self.grid.currentText(),
                                     self.model.currentText()), "Distortion")

    def _show(self, outcomes: list[PlateOutcome]) -> None:
        for o in outcomes:
            s = o.summary
            self.pictures[o.view].setPixmap(_pixmap(o.picture))
            self.texts[o.view].setText(f"{s['holes']} holes ({s['discarded']} discarded); residual RMS "
                                       f"{s['rms_px']:.3f} px / {s['rms_mm']:.4f} mm, max {s['max_px']:.3f} px")
            self.corrections[o.view] = o.correction
        self.status.setText("Fitted: check the residual map, then Next to accept.")
        self.completeChanged.emit()

    def isComplete(self) -> bool:  # noqa: N802 (Qt override)
        wanted = {k for k, e in enumerate(self.plates) if e.text().strip()}
        return not self.runner.is_running() and wanted == set(self.corrections)


class BeadPage(_FitPage):
    def __init__(self, plate_page: PlatePage) -> None:
        super().__init__("View geometry", "Bead-phantom image of each view and the phantom's bead coordinates "
                         "(CSV x,y,z in mm; the first bead is the larger marker). Green circles: matched beads "
                         "reprojected; the RMS reprojection error is given per view.", "Detect beads and calibrate")
        self.plate_page = plate_page
        self.images = [QLineEdit() for _ in range(N_VIEWS)]
        for k, edit in enumerate(self.images):
            edit.setObjectName(f"beads{k + 1}")
            self.form.addRow(f"Bead image, view {k + 1}:", _path_row(edit, "Bead image", "Images (*)"))
        self.phantom = QLineEdit()
        self.phantom.setObjectName("phantom")
        self.form.addRow("Phantom CSV:", _path_row(self.phantom, "Bead phantom", "CSV (*.csv);;All files (*)"))
        self.pitch = QDoubleSpinBox()
        self.pitch.setRange(0.0, 5.0)
        self.pitch.setDecimals(4)
        self.pitch.setSpecialValueText("unknown")
        self.pitch.setSuffix(" mm")
        self.form.addRow("Detector pixel pitch:", self.pitch)
        self.out_dir = QLineEdit()
        self.out_dir.setObjectName("out_dir")
        self.form.addRow("Write views to:", _path_row(self.out_dir, "Output folder", "", folder=True))
        self.results: dict[int, object] = {}
        self.run_button.clicked.connect(self.run)
        self.runner.finished.connect(self._show)
        self.out_dir.textChanged.connect(lambda _t: self.completeChanged.emit())

    def run(self) -> None:
        images = {k: e.text().strip() for k, e in enumerate(self.images) if e.text().strip()}
        if not images or not self.phantom.text().strip():
            self.status.setText("Choose at least one bead image and the phantom CSV.")
            return
        self.results = {}
        pitch = self.pitch.value() or None
        self.runner.start(bead_task(images, self.phantom.text().strip(), self.plate_page.corrections, pitch), "Beads")

    def _show(self, outcomes: list[BeadOutcome]) -> None:
        for o in outcomes:
            c = o.calibration
            self.pictures[o.view].setPixmap(_pixmap(o.picture))
            self.texts[o.view].setText(f"{c.used} beads matched ({c.detections} detected); reprojection RMS "
                                       f"{c.rms_px:.3f} px, max {c.max_px:.3f} px; source-intensifier "
                                       f"distance {c.view.distance:.1f} mm"
                                       + (" (pixel pitch assumed)" if c.view.extra.get("pitch_assumed") else ""))
            self.results[o.view] = c
        self.status.setText("Calibrated: check the reprojections, then Finish to write the views.")
        self.completeChanged.emit()

    def isComplete(self) -> bool:  # noqa: N802 (Qt override)
        return not self.runner.is_running() and bool(self.results) and bool(self.out_dir.text().strip())


class CalibrationWizard(QWizard):
    """Plate -> beads -> views written to a folder (``self.views``, ``self.written``)."""

    def __init__(self, parent: QWidget | None = None) -> None:
        super().__init__(parent)
        self.setWindowTitle("Calibrate fluoroscope")
        self.plate_page = PlatePage()
        self.bead_page = BeadPage(self.plate_page)
        self.addPage(self.plate_page)
        self.addPage(self.bead_page)
        self.views: list = []
        self.written: list[Path] = []
        self.resize(760, 660)

    def accept(self) -> None:
        from fluorogui.io.corrections import attach_correction
        from fluorogui.io.errors import InputError
        from fluorogui.workflow.calibration import write_views

        views = {}
        for k, result in sorted(self.bead_page.results.items()):
            view = result.view
            if k in self.plate_page.corrections:
                view = attach_correction(view, self.plate_page.corrections[k])
            views[k] = view
        try:
            written = write_views(views, self.bead_page.out_dir.text().strip())
        except (InputError, OSError) as exc:
            self.bead_page.status.setText(f"<span style='color:#c62828'>{exc}</span>")
            return
        views = [views[k] for k in sorted(views)]
        self.views, self.written = views, written
        super().accept()
