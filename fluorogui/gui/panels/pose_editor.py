"""The pose editor: six spin boxes (x, y, z in mm; alpha, beta, gamma in degrees) with step sizes.

It shows one component's pose and emits ``pose_edited`` when the user changes a value (typing,
arrows, wheel or a keyboard nudge); ``set_pose`` from the program never emits.
"""
from __future__ import annotations

import numpy as np
from PySide6.QtCore import Signal
from PySide6.QtWidgets import QComboBox, QDoubleSpinBox, QFormLayout, QGridLayout, QLabel, QVBoxLayout, QWidget

AXES = ("x", "y", "z", "alpha", "beta", "gamma")
AXIS_LABELS = ("x (mm)", "y (mm)", "z (mm)", "α about x (°)", "β about y (°)", "γ about z (°)")
AXIS_TIPS = (
    "Translation along the calibration's x axis",
    "Translation along the calibration's y axis",
    "Translation along the calibration's z axis",
    "Rotation about the calibration's x axis (applied first; R = Ry(β) Rz(γ) Rx(α)); not a knee angle",
    "Rotation about the calibration's y axis (applied last); not a knee angle",
    "Rotation about the calibration's z axis; not a knee angle",
)
TRANSLATION_STEPS = (0.1, 0.5, 1.0, 5.0, 10.0)
ROTATION_STEPS = (0.1, 0.5, 1.0, 5.0, 10.0)


class PoseEditor(QWidget):
    """Six spin boxes bound to one component's pose."""

    pose_edited = Signal(object)  # np.ndarray (6,)

    def __init__(self, parent: QWidget | None = None) -> None:
        super().__init__(parent)
        self.title = QLabel("No model")
        self.title.setObjectName("poseTitle")
        font = self.title.font()
        font.setBold(True)
        self.title.setFont(font)
        self.frame_note = QLabel("Pose of the model in the calibration frame. Knee angles (flexion, varus, "
                                 "rotation) are in the Kinematics panel.")
        self.frame_note.setObjectName("hint")
        self.frame_note.setWordWrap(True)
        self.spins: list[QDoubleSpinBox] = []
        self.sd_labels: list[QLabel] = []
        grid = QGridLayout()
        grid.setHorizontalSpacing(8)
        for i, (label, tip) in enumerate(zip(AXIS_LABELS, AXIS_TIPS)):
            spin = QDoubleSpinBox()
            spin.setObjectName(f"pose_{AXES[i]}")
            spin.setDecimals(3)
            spin.setRange(-5000.0, 5000.0) if i < 3 else spin.setRange(-360.0, 360.0)
            spin.setKeyboardTracking(False)
            spin.setAccelerated(True)
            spin.setToolTip(tip)
            spin.setAccessibleName(label)
            spin.valueChanged.connect(self._user_changed)
            name = QLabel(label)
            name.setBuddy(spin)
            grid.addWidget(name, i, 0)
            grid.addWidget(spin, i, 1)
            self.spins.append(spin)
            sd = QLabel("")
            sd.setObjectName(f"sd_{AXES[i]}")
            sd.setToolTip("Standard deviation of the matched value, from how well the outlines pin it down")
            grid.addWidget(sd, i, 2)
            self.sd_labels.append(sd)
        # the body's own turns: near gamma = +-90 deg alpha and beta trade with each other, so their
        # SDs are large (the real femur's about 1 deg) while the pose is pinned down to a tenth of that
        self.body_sd = QLabel("")
        self.body_sd.setObjectName("sd_body")
        self.body_sd.setWordWrap(True)
        self.body_sd.setToolTip(
            "How well the outlines pin down the model's turns about its own x, y and z axes (one standard "
            "deviation). The quality checks judge these. The ± beside α and β can be much larger when γ is "
            "near ±90°: those two angles then trade with each other, even though the pose itself is well "
            "determined.")
        self.translation_step = QComboBox()
        self.rotation_step = QComboBox()
        for combo, steps, unit in ((self.translation_step, TRANSLATION_STEPS, "mm"),
                                   (self.rotation_step, ROTATION_STEPS, "°")):
            for s in steps:
                combo.addItem(f"{s:g} {unit}", s)
            combo.setCurrentIndex(2)
            combo.currentIndexChanged.connect(self._apply_steps)
        steps_form = QFormLayout()
        steps_form.addRow("Move step", self.translation_step)
        steps_form.addRow("Turn step", self.rotation_step)
        hint = QLabel("Nudge: Ctrl+arrows / Ctrl+PgUp/PgDn move, add Shift to turn")
        hint.setWordWrap(True)
        hint.setObjectName("hint")
        layout = QVBoxLayout(self)
        layout.addWidget(self.title)
        layout.addWidget(self.frame_note)
        layout.addLayout(grid)
        layout.addWidget(self.body_sd)
        layout.addLayout(steps_form)
        layout.addWidget(hint)
        layout.addStretch(1)
        self._updating = False
        self._apply_steps()

    def _apply_steps(self) -> None:
        for i, spin in enumerate(self.spins):
            spin.setSingleStep(self.translation_step.currentData() if i < 3 else self.rotation_step.currentData())

    def set_component(self, name: str | None) -> None:
        self.title.setText(f"Pose of the {name} component (calibration frame)" if name else "No model")
        self.setEnabled(bool(name))

    def set_pose(self, pose) -> None:
        pose = np.asarray(pose, dtype=float)
        self._updating = True
        try:
            for spin, value in zip(self.spins, pose):
                spin.setValue(float(value))
        finally:
            self._updating = False

    def set_uncertainty(self, sd, sd_body=None) -> None:
        """Show the match's standard deviations (mm, deg; None or inf: not determined) beside
        the values, or nothing (``sd`` None: a pose placed or edited by hand); and below
        them, where the match kept them (``sd_body``: x, y, z mm then the turns about the
        model's own axes, deg), the turns' SDs."""
        for i, label in enumerate(self.sd_labels):
            value = None if sd is None else sd[i]
            if sd is None:
                label.setText("")
            elif value is None or not np.isfinite(value):
                label.setText("± ?")
            else:
                label.setText(f"± {value:.3f}")
        turns = None if sd is None or sd_body is None or len(sd_body) != 6 else sd_body[3:]
        if turns is None:
            self.body_sd.setText("")
            self.body_sd.hide()
            return
        shown = ["?" if v is None or not np.isfinite(v) else f"{v:.3f}" for v in turns]
        self.body_sd.setText(f"Turns about the model's own x, y, z axes: ± {shown[0]}, {shown[1]}, {shown[2]}°")
        self.body_sd.show()

    def pose(self) -> np.ndarray:
        return np.array([spin.value() for spin in self.spins])

    def nudge(self, axis: int, direction: int) -> None:
        """Step one variable by the current step size (keyboard nudges)."""
        spin = self.spins[axis]
        spin.setValue(spin.value() + direction * spin.singleStep())

    def _user_changed(self, _value: float) -> None:
        if not self._updating:
            self.pose_edited.emit(self.pose())
