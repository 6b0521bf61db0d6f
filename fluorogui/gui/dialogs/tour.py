"""A short, dismissable guided tour of the window, shown on the demo's first run (and
from *Help → Guided tour*): which panel does what, and how to outline, place, match,
track and export. Whether it was shown is remembered in QSettings (``tour/shown``)."""
from __future__ import annotations

from PySide6.QtCore import Qt
from PySide6.QtWidgets import QDialog, QHBoxLayout, QLabel, QPushButton, QVBoxLayout

STEPS = (
    ("Welcome", "This is the demo: two X-ray views of a knee implant that bends over four frames. "
                "This tour takes a minute; close it at any time (Help → Guided tour brings it back)."),
    ("The two views", "The centre shows view 1 and view 2. The coloured dots and line are the implant's "
                      "outline; the lighter dots are the 3D model projected into the image. Wheel zooms, "
                      "right-drag sets the contrast, F fits."),
    ("Place", "Find implants (Ctrl+F) places every component automatically. By hand: the Place tool (C), "
              "then click the component in view 1 and in view 2."),
    ("Outline", "The toolbar's tools edit the outline: Pick contour (P), Move (M), Insert (I), Delete (D), "
                "Erase (E), Lasso (L), Close gap (G). The status bar says what the current tool does."),
    ("Match", "F5 matches the active component (K switches component), Ctrl+F5 both. The Matcher tab on "
              "the right shows the objective falling and says 'needs review' when a check fails."),
    ("Accept and track", "Ctrl+Return accepts a pose you have checked. Shift+F5 tracks the following frames; "
                         "the Frames bar at the bottom shows each frame's state (green accepted, red review)."),
    ("Save and export", "Ctrl+S saves the session; the File menu exports poses and kinematics. Help → Quick "
                        "start and F1 (shortcuts) are there whenever you need them."),
)


class Tour(QDialog):
    """The tour: one step at a time, Back / Next / Close."""

    def __init__(self, parent=None):
        super().__init__(parent)
        self.setObjectName("tourDialog")
        self.setWindowTitle("Guided tour")
        self.setWindowFlag(Qt.WindowType.Tool)
        self.step = 0
        self.title = QLabel()
        self.title.setObjectName("tourTitle")
        self.text = QLabel()
        self.text.setWordWrap(True)
        self.text.setMinimumWidth(380)
        self.back_button = QPushButton("Back")
        self.next_button = QPushButton("Next")
        self.close_button = QPushButton("Close tour")
        self.back_button.clicked.connect(lambda: self.show_step(self.step - 1))
        self.next_button.clicked.connect(self._next)
        self.close_button.clicked.connect(self.close)
        buttons = QHBoxLayout()
        buttons.addWidget(self.close_button)
        buttons.addStretch(1)
        buttons.addWidget(self.back_button)
        buttons.addWidget(self.next_button)
        layout = QVBoxLayout(self)
        layout.addWidget(self.title)
        layout.addWidget(self.text, 1)
        layout.addLayout(buttons)
        self.next_button.setDefault(True)
        self.next_button.setFocus()
        self.show_step(0)

    def _next(self) -> None:
        if self.step + 1 < len(STEPS):
            self.show_step(self.step + 1)
        else:
            self.close()

    def show_step(self, step: int) -> None:
        self.step = max(0, min(step, len(STEPS) - 1))
        title, text = STEPS[self.step]
        self.title.setText(f"<b>{title}</b> ({self.step + 1} of {len(STEPS)})")
        self.text.setText(text)
        self.back_button.setEnabled(self.step > 0)
        self.next_button.setText("Done" if self.step == len(STEPS) - 1 else "Next")


def start_tour(window, force: bool = False) -> Tour | None:
    """Show the tour (once per user unless ``force``); returns it, or None if already seen."""
    if not force and str(window.settings.value("tour/shown", "false")).lower() == "true":
        return None
    window.settings.setValue("tour/shown", "true")
    tour = Tour(window)
    tour.setAttribute(Qt.WidgetAttribute.WA_DeleteOnClose)
    tour.show()
    geometry = window.frameGeometry()
    tour.move(geometry.center() - tour.rect().center())
    return tour
