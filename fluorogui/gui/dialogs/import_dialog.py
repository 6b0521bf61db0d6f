"""The "Import session" dialog: pick calibrations, images and models, get a Project.

A thin front end of ``fluorogui.io.importer``: every check happens in ``import_session``
when the user presses OK. A bad file keeps the dialog open with the problem shown in red
under the form (and the field at fault outlined); on success ``self.project`` holds the
new Project and the dialog closes accepted. "From folder…" fills every field from a
folder laid out like ``data/biplane-tka`` (or, with view 2 left empty, a single-plane one like
``data/single-plane-tka``). Under each view's fields a preview shows the first frame, the
frame count, and the format and bit depth of the images (``preview_image_source``).
``fill(**paths)`` sets fields from code (tests,
drag and drop); paths can also be dropped on a field, or a whole folder on the dialog.
The frame rate (the project's time base) is what the user gives, else what a video or
DICOM declares (shown in its preview; ``source_frame_rate``).
"""
from __future__ import annotations

from pathlib import Path

import numpy as np
from PySide6.QtCore import Qt, QTimer
from PySide6.QtGui import QAction, QGuiApplication, QImage, QPixmap
from PySide6.QtWidgets import (
    QComboBox,
    QDialog,
    QDialogButtonBox,
    QDoubleSpinBox,
    QFileDialog,
    QFormLayout,
    QFrame,
    QHBoxLayout,
    QLabel,
    QLineEdit,
    QMenu,
    QPushButton,
    QScrollArea,
    QToolButton,
    QVBoxLayout,
    QWidget,
)

from fluorogui.core.records import Project
from fluorogui.io.errors import InputError
from fluorogui.io.images import IMAGE_SUFFIXES, VIDEO_SUFFIXES
from fluorogui.io.importer import (
    CALIBRATION_SUFFIXES,
    detect_biplane_folder,
    detect_single_plane_folder,
    import_session,
    preview_image_source,
    resolve_image_source,
    source_frame_rate,
)
from fluorogui.io.meshes.read import MESH_SUFFIXES
from fluorogui.io.motion_files import MAX_FPS, store_frame_rate

#: Separator of several image files in one field.
FILE_SEPARATOR = "; "
ERROR_STYLE = "color: #c62828;"
BAD_FIELD_STYLE = "QLineEdit { border: 1px solid #c62828; }"


def _filter(title: str, suffixes) -> str:
    return f"{title} ({' '.join('*' + s for s in suffixes)});;All files (*)"


CALIBRATION_FILTER = _filter("Calibrations", CALIBRATION_SUFFIXES)
IMAGE_FILTER = _filter("Images", IMAGE_SUFFIXES)
VIDEO_FILTER = _filter("Videos", VIDEO_SUFFIXES)
CSV_FILTER = _filter("Pairs CSV", (".csv",))
MESH_FILTER = _filter("Surface models", MESH_SUFFIXES)

# key, label, kind, tooltip
_VIEW_FIELDS = [
    ("calibration{k}", "Calibration:", "calibration",
     "Projection geometry of view {k}: MayaCam 2.0 / 1.0, JointTrack JT_INTCALIB or fluorogui JSON."),
    ("images{k}", "Images:", "images",
     "Images of view {k}: a folder (files in name order), several image files, or one video.\n"
     "Not needed when a pairs CSV is given."),
]
_OTHER_FIELDS = [
    ("pairs_csv", "Pairs CSV:", "csv",
     "Optional. Lines 'frame,cam1,cam2' with image paths relative to the CSV;\n"
     "it decides the frames and which images go together."),
    ("femoral", "Femoral component:", "mesh", "Surface model of the femoral component (STL, PLY, OBJ, VTK; in mm)."),
    ("tibial", "Tibial component:", "mesh", "Surface model of the tibial component (STL, PLY, OBJ, VTK; in mm)."),
]
FIELD_KEYS = ("calibration1", "images1", "calibration2", "images2", "pairs_csv", "femoral", "tibial")
#: Side (px) of the first-frame previews.
PREVIEW_PX = 96
REQUIRED_LABELS = {
    "calibration1": "the calibration of view 1",
    "calibration2": "the calibration of view 2",
    "images1": "the images of view 1",
    "images2": "the images of view 2",
    "femoral": "the femoral component model",
    "tibial": "the tibial component model",
}


class _PathEdit(QLineEdit):
    """A line edit that takes dropped files or folders (several are joined)."""

    def __init__(self, parent: QWidget | None = None) -> None:
        super().__init__(parent)
        self.setAcceptDrops(True)
        self.setClearButtonEnabled(True)

    def dragEnterEvent(self, event) -> None:  # noqa: N802 (Qt override)
        if event.mimeData().hasUrls():
            event.acceptProposedAction()
        else:
            super().dragEnterEvent(event)

    def dropEvent(self, event) -> None:  # noqa: N802 (Qt override)
        paths = [u.toLocalFile() for u in event.mimeData().urls() if u.isLocalFile()]
        if paths:
            self.setText(FILE_SEPARATOR.join(paths))
            event.acceptProposedAction()
        else:
            super().dropEvent(event)


class ImportDialog(QDialog):
    """Collects the files of a biplane session and imports them into ``self.project``."""

    def __init__(self, parent: QWidget | None = None, start_dir: str | Path | None = None) -> None:
        super().__init__(parent)
        self.setWindowTitle("Import session")
        self.setAcceptDrops(True)
        self.project: Project | None = None
        self.fields: dict[str, QLineEdit] = {}
        self._start_dir = str(start_dir or Path.home())

        intro = QLabel("Choose the calibration and images of each view (one view for a single-plane study) and "
                       "the implant models, or fill everything from a session folder.")
        intro.setWordWrap(True)
        self.from_folder_button = QPushButton("From folder…")
        self.from_folder_button.setToolTip(
            "Fill every field from one folder holding calibration/, cam1/, cam2/, models/ and pairs.csv")
        self.from_folder_button.clicked.connect(self.choose_folder)
        top = QHBoxLayout()
        top.addWidget(intro, 1)
        top.addWidget(self.from_folder_button, 0, Qt.AlignmentFlag.AlignTop)

        form = QFormLayout()
        form.setFieldGrowthPolicy(QFormLayout.FieldGrowthPolicy.AllNonFixedFieldsGrow)
        form.setLabelAlignment(Qt.AlignmentFlag.AlignRight | Qt.AlignmentFlag.AlignVCenter)
        self.previews: dict[int, QLabel] = {}
        self.preview_texts: dict[int, QLabel] = {}
        self._preview_timer = QTimer(self)
        self._preview_timer.setSingleShot(True)
        self._preview_timer.setInterval(250)
        self._preview_timer.timeout.connect(self.update_previews)
        for k in (1, 2):
            form.addRow(self._heading(f"View {k}" + (" (leave empty for a single-plane session)" if k == 2 else "")))
            for key, label, kind, tip in _VIEW_FIELDS:
                self._add_field(form, key.format(k=k), label, kind, tip.format(k=k))
            self.fields[f"images{k}"].textChanged.connect(lambda _text: self._preview_timer.start())
            form.addRow("", self._preview_row(k))
        form.addRow(self._heading("Frames"))
        self._add_field(form, *_OTHER_FIELDS[0])
        self.frame_rate = QDoubleSpinBox()
        self.frame_rate.setObjectName("import_fps")
        self.frame_rate.setRange(0.0, MAX_FPS)
        self.frame_rate.setDecimals(3)
        self.frame_rate.setSuffix(" frames/s")
        self.frame_rate.setSpecialValueText("from the images, if they say")
        self.frame_rate.setToolTip("The images' frame rate: time = frame number / frame rate (C3D, OpenSim .trc and "
                                   ".mot exports need it). Videos and DICOM runs usually say it themselves.")
        form.addRow("Frame rate:", self.frame_rate)
        form.addRow(self._heading("Implant models"))
        for spec in _OTHER_FIELDS[1:]:
            self._add_field(form, *spec)
        self.side = QComboBox()
        self.side.setObjectName("import_side")
        for text, value in (("Right knee", "right"), ("Left knee", "left"), ("Not known yet", None)):
            self.side.addItem(text, value)
        self.side.setToolTip("Which knee: the signs of varus, rotation and medial translation depend on it "
                             "(can be changed later in the Kinematics tab)")
        self.side.setCurrentIndex(2)  # asked, not assumed: the Kinematics tab says "not set" until chosen
        form.addRow("Knee", self.side)

        self.error_label = QLabel()
        self.error_label.setObjectName("import_error")
        self.error_label.setStyleSheet(ERROR_STYLE)
        self.error_label.setWordWrap(True)
        self.error_label.setTextInteractionFlags(Qt.TextInteractionFlag.TextSelectableByMouse)
        self.error_label.hide()

        self.buttons = QDialogButtonBox(QDialogButtonBox.StandardButton.Ok | QDialogButtonBox.StandardButton.Cancel)
        self.buttons.button(QDialogButtonBox.StandardButton.Ok).setText("Import")
        self.buttons.accepted.connect(self.accept)
        self.buttons.rejected.connect(self.reject)

        fields = QWidget()
        column = QVBoxLayout(fields)
        column.setContentsMargins(0, 0, 0, 0)
        column.addLayout(form)
        column.addWidget(self.error_label)
        column.addStretch(1)
        self.form_area = QScrollArea()  # a short screen scrolls the fields, the buttons stay in sight
        self.form_area.setObjectName("import_fields")
        self.form_area.setWidgetResizable(True)
        self.form_area.setFrameShape(QFrame.Shape.NoFrame)
        self.form_area.setWidget(fields)
        layout = QVBoxLayout(self)
        layout.addLayout(top)
        layout.addWidget(self.form_area, 1)
        layout.addWidget(self.buttons)
        wanted = top.sizeHint().height() + fields.sizeHint().height() + self.buttons.sizeHint().height() + 48
        screen = self.screen() or QGuiApplication.primaryScreen()
        room = screen.availableGeometry().height() - 60 if screen is not None else wanted  # less a title bar
        self.resize(720, max(320, min(wanted, room)))

    # -- building --------------------------------------------------------------------------
    @staticmethod
    def _heading(text: str) -> QLabel:
        label = QLabel(f"<b>{text}</b>")
        label.setContentsMargins(0, 6, 0, 0)
        return label

    def _add_field(self, form: QFormLayout, key: str, label: str, kind: str, tooltip: str) -> None:
        edit = _PathEdit()
        edit.setObjectName(key)
        edit.setToolTip(tooltip)
        edit.setPlaceholderText({
            "calibration": "calibration file",
            "images": "folder, image files or a video",
            "csv": "optional",
            "mesh": "surface model file",
        }[kind])
        edit.textChanged.connect(lambda _text, e=edit: e.setStyleSheet(""))
        button = QToolButton()
        button.setText("Browse…")
        button.setToolTip(f"Choose {label.rstrip(':').lower()}")
        if kind == "images":
            menu = QMenu(button)
            for text, chooser in (("Folder…", self._choose_image_folder), ("Image files…", self._choose_image_files),
                                  ("Video…", self._choose_video)):
                action = QAction(text, menu)
                action.triggered.connect(lambda _checked=False, c=chooser, e=edit: c(e))
                menu.addAction(action)
            button.setMenu(menu)
            button.setPopupMode(QToolButton.ToolButtonPopupMode.InstantPopup)
        else:
            name_filter = {"calibration": CALIBRATION_FILTER, "csv": CSV_FILTER, "mesh": MESH_FILTER}[kind]
            button.clicked.connect(lambda _checked=False, e=edit, f=name_filter, t=label: self._choose_file(e, t, f))
        row = QHBoxLayout()
        row.setContentsMargins(0, 0, 0, 0)
        row.addWidget(edit, 1)
        row.addWidget(button)
        holder = QWidget()
        holder.setLayout(row)
        label_widget = QLabel(label)
        label_widget.setBuddy(edit)
        label_widget.setToolTip(tooltip)
        form.addRow(label_widget, holder)
        self.fields[key] = edit

    def _preview_row(self, k: int) -> QWidget:
        picture = QLabel()
        picture.setObjectName(f"preview{k}")
        picture.setFixedSize(PREVIEW_PX, PREVIEW_PX)
        picture.setAlignment(Qt.AlignmentFlag.AlignCenter)
        picture.setStyleSheet("background: #202020; color: #909090;")
        picture.setText("no images")
        text = QLabel()
        text.setObjectName(f"preview_text{k}")
        text.setWordWrap(True)
        text.setTextInteractionFlags(Qt.TextInteractionFlag.TextSelectableByMouse)
        row = QHBoxLayout()
        row.setContentsMargins(0, 0, 0, 0)
        row.addWidget(picture)
        row.addWidget(text, 1)
        holder = QWidget()
        holder.setLayout(row)
        self.previews[k], self.preview_texts[k] = picture, text
        return holder

    def update_previews(self) -> None:
        """Show each view's first frame, frame count, format and bit depth (or the problem)."""
        for k in (1, 2):
            source = self._image_source(self.fields[f"images{k}"].text())
            picture, text = self.previews[k], self.preview_texts[k]
            if source is None:
                picture.clear()
                picture.setText("no images")
                text.setText("")
                continue
            try:
                preview = preview_image_source(source)
            except (InputError, ValueError) as exc:
                picture.clear()
                picture.setText("?")
                text.setText(f"<span style='{ERROR_STYLE}'>{exc}</span>")
                continue
            picture.setPixmap(_thumbnail(preview.first))
            rate = _declared_rate(source)
            text.setText(preview.describe() + (f", {rate[0]:g} frames/s" if rate else ""))

    @staticmethod
    def _image_source(field_text: str):
        parts = [p.strip() for p in field_text.split(FILE_SEPARATOR.strip()) if p.strip()]
        if not parts:
            return None
        return Path(parts[0]) if len(parts) == 1 else [Path(p) for p in parts]

    # -- filling -------------------------------------------------------------------------------
    def fill(self, **paths) -> None:
        """Set fields by key (see ``FIELD_KEYS``): a path, or a list of paths for images."""
        unknown = set(paths) - set(self.fields)
        if unknown:
            raise KeyError(f"unknown import fields: {', '.join(sorted(unknown))}")
        for key, value in paths.items():
            if value is None:
                text = ""
            elif isinstance(value, (list, tuple)):
                text = FILE_SEPARATOR.join(str(v) for v in value)
            else:
                text = str(value)
            self.fields[key].setText(text)

    def fill_from_folder(self, folder) -> bool:
        """Fill the fields from a biplane folder; show why not when it is not one."""
        found = detect_biplane_folder(folder) or detect_single_plane_folder(folder)
        if found is None:
            self._show_error(f"{folder}: not a session folder (expected calibration/, cam1/ and cam2/, "
                             "or one calibration file with its images for a single-plane session)")
            return False
        values = {"pairs_csv": found["pairs_csv"], "calibration2": None, "images2": None}
        for k, (calibration, images) in enumerate(zip(found["calibrations"], found["image_sources"]), start=1):
            values[f"calibration{k}"] = calibration
            values[f"images{k}"] = images
        for component in ("femoral", "tibial"):
            values[component] = found["models"].get(component)
        self.fill(**values)
        self._start_dir = str(folder)
        self.error_label.hide()
        return True

    def import_arguments(self) -> dict:
        """The keyword arguments of ``import_session`` from the fields (ValueError if incomplete)."""
        text = {key: edit.text().strip() for key, edit in self.fields.items()}
        single = not text["calibration2"] and not text["images2"] and not text["pairs_csv"]
        n_views = 1 if single else 2
        required = [k for k in REQUIRED_LABELS if not (text["pairs_csv"] and k.startswith("images"))
                    and not (single and k.endswith("2"))]
        missing = [REQUIRED_LABELS[k] for k in required if not text[k] and k not in ("femoral", "tibial")]
        if not text["femoral"] and not text["tibial"]:
            missing.append("at least one implant model")
        if missing:
            raise ValueError("Choose " + ", ".join(missing) + ".")
        images = [self._image_source(text[f"images{k}"]) for k in range(1, n_views + 1)]
        return {
            "calibrations": [Path(text[f"calibration{k}"]) for k in range(1, n_views + 1)],
            "image_sources": [] if text["pairs_csv"] else images,
            "models": {c: Path(text[c]) for c in ("femoral", "tibial") if text[c]},
            "pairs_csv": Path(text["pairs_csv"]) if text["pairs_csv"] else None,
        }

    # -- OK ----------------------------------------------------------------------------------
    def accept(self) -> None:
        """Import; on a bad file show the problem inline and stay open."""
        try:
            arguments = self.import_arguments()
        except ValueError as exc:
            self._show_error(str(exc))
            return
        QGuiApplication.setOverrideCursor(Qt.CursorShape.WaitCursor)
        try:
            project = import_session(**arguments)
        except (InputError, ValueError) as exc:
            self._show_error(str(exc), getattr(exc, "path", None))
            return
        finally:
            QGuiApplication.restoreOverrideCursor()
        if self.frame_rate.value() > 0:
            store_frame_rate(project.settings, self.frame_rate.value(), "user")
        if self.side.currentData():
            from fluorogui.workflow.session.knee import KNEE_KEY

            project.settings.setdefault(KNEE_KEY, {})["side"] = self.side.currentData()
        self.project = project
        self.error_label.hide()
        super().accept()

    def _show_error(self, message: str, path: str | None = None) -> None:
        self.error_label.setText(message)
        self.error_label.show()
        if path:
            for edit in self.fields.values():
                if _mentions(edit.text(), path):
                    edit.setStyleSheet(BAD_FIELD_STYLE)

    # -- choosers ----------------------------------------------------------------------------
    def choose_folder(self) -> None:
        folder = QFileDialog.getExistingDirectory(self, "Session folder", self._start_dir)
        if folder:
            self.fill_from_folder(folder)

    def _where(self, edit: QLineEdit) -> str:
        first = edit.text().split(FILE_SEPARATOR.strip())[0].strip()
        return str(Path(first).parent) if first else self._start_dir

    def _remember(self, path: str) -> None:
        self._start_dir = str(Path(path).parent)

    def _choose_file(self, edit: QLineEdit, title: str, name_filter: str) -> None:
        path, _ = QFileDialog.getOpenFileName(self, title.rstrip(":"), self._where(edit), name_filter)
        if path:
            edit.setText(path)
            self._remember(path)

    def _choose_image_folder(self, edit: QLineEdit) -> None:
        folder = QFileDialog.getExistingDirectory(self, "Image folder", self._where(edit))
        if folder:
            edit.setText(folder)
            self._start_dir = folder

    def _choose_image_files(self, edit: QLineEdit) -> None:
        paths, _ = QFileDialog.getOpenFileNames(self, "Image files", self._where(edit), IMAGE_FILTER)
        if paths:
            edit.setText(FILE_SEPARATOR.join(paths))
            self._remember(paths[0])

    def _choose_video(self, edit: QLineEdit) -> None:
        path, _ = QFileDialog.getOpenFileName(self, "Video", self._where(edit), VIDEO_FILTER)
        if path:
            edit.setText(path)
            self._remember(path)

    # -- drop a whole folder on the dialog ---------------------------------------------------
    def dragEnterEvent(self, event) -> None:  # noqa: N802 (Qt override)
        urls = event.mimeData().urls()
        if len(urls) == 1 and urls[0].isLocalFile() and Path(urls[0].toLocalFile()).is_dir():
            event.acceptProposedAction()

    def dropEvent(self, event) -> None:  # noqa: N802 (Qt override)
        urls = event.mimeData().urls()
        if len(urls) == 1 and urls[0].isLocalFile():
            self.fill_from_folder(urls[0].toLocalFile())
            event.acceptProposedAction()


def _thumbnail(image: np.ndarray) -> QPixmap:
    """A PREVIEW_PX pixmap of a float image in [0, 1], windowed on its 1st-99.5th percentiles."""
    step = max(1, int(max(image.shape) // (2 * PREVIEW_PX)))
    small = np.asarray(image[::step, ::step], dtype=np.float32)
    lo, hi = np.percentile(small, [1.0, 99.5])
    gray = np.ascontiguousarray(np.clip((small - lo) / max(hi - lo, 1e-6) * 255, 0, 255).astype(np.uint8))
    qimage = QImage(gray.data, gray.shape[1], gray.shape[0], gray.strides[0], QImage.Format.Format_Grayscale8)
    return QPixmap.fromImage(qimage.copy()).scaled(PREVIEW_PX, PREVIEW_PX, Qt.AspectRatioMode.KeepAspectRatio,
                                                    Qt.TransformationMode.SmoothTransformation)


def _declared_rate(source) -> tuple[float, str] | None:
    """The frame rate the first image of a source declares (a video's, a DICOM's), or None."""
    try:
        frames = resolve_image_source(source)
    except (InputError, ValueError):
        return None
    return source_frame_rate(frames[0]) if frames else None


def _mentions(field_text: str, path: str) -> bool:
    """Whether a field names ``path`` or a folder that contains it."""
    target = Path(path).absolute()
    for part in field_text.split(FILE_SEPARATOR.strip()):
        part = part.strip()
        if not part:
            continue
        named = Path(part).expanduser().absolute()
        if named == target or named in target.parents:
            return True
    return False
