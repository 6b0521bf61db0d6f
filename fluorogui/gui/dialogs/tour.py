"""A short, dismissable guided tour of the window, shown on the demo's first run (and
from *Help → Guided tour*): which panel does what, and how to place, match, check the
outline, track and export. Whether it was shown is remembered in QSettings (``tour/shown``).

The box is as large as its longest text needs, and each step puts it where it covers
none of the widgets that step describes (moving only when it must). Its texts say what
the demo really shows: before a match the lines in the images are the projected models,
and there is no outline for the outline tools to edit yet.
"""
from __future__ import annotations

from PySide6.QtCore import QPoint, QRect, Qt
from PySide6.QtGui import QGuiApplication
from PySide6.QtWidgets import QDialog, QHBoxLayout, QLabel, QLayout, QPushButton, QVBoxLayout, QWidget

#: (title, text, what it describes: attribute paths of the main window, or #objectName)
STEPS = (
    ("Welcome", "This is the demo: two X-ray views of a knee implant that bends over four frames, with "
                "its true poses known. This tour takes a minute; close it at any time (Help → Guided tour "
                "brings it back).", ()),
    ("The two views", "The centre shows view 1 and view 2. The lines over the implants are the 3D models "
                      "projected into each image at their current pose (here placed near the implants, not "
                      "yet matched). Wheel zooms, right-drag sets the contrast, F fits.", ("panels",)),
    ("Place", "Find implants (Ctrl+F) places every component automatically. By hand: the Place tool (C), "
              "then click the component in view 1 and in view 2.", ("matcher.place_button",)),
    ("Match", "F5 matches the active component (K switches component), Ctrl+F5 both. The model slides onto "
              "the implant; the Matcher tab on the right shows the objective falling and says 'needs "
              "review' when a check fails.",
     ("matcher.run_button", "matcher.run_both_button", "matcher.plot")),
    ("Check the outline", "A match also outlines each implant from the image's edges: dots in the "
                          "component's colour, under the model's line where the two agree (it turns green "
                          "there, red where they differ). To fix an outline use the toolbar's tools: Move "
                          "(M), Insert (I), Delete (D), Erase (E), Lasso (L), Close gap (G), or Pick "
                          "contour (P) to take an edge whole; then match again. The status bar says what "
                          "the current tool does.", ("#mainToolbar", "panels")),
    ("Accept and track", "Ctrl+Return accepts a pose you have checked. Shift+F5 tracks the following frames; "
                         "the Frames bar at the bottom shows each frame's state (green accepted, red review).",
     ("matcher.accept_button", "matcher.track_button", "matcher.track_both_button", "#timelineDock")),
    ("Save and export", "Ctrl+S saves the session; the File menu exports poses and kinematics. Help → Quick "
                        "start and F1 (shortcuts) are there whenever you need them.", ("menuBar",)),
)
MARGIN = 12  # px between the box and the window's edge


def target_widgets(window: QWidget, names) -> list[QWidget]:
    """The visible widgets a step describes: attribute paths (``matcher.run_button``; a
    list such as ``panels`` gives each; a method such as ``menuBar`` is called) or
    ``#objectName``."""
    found = []
    for name in names:
        if name.startswith("#"):
            value = window.findChild(QWidget, name[1:])
        else:
            value = window
            for part in name.split("."):
                value = getattr(value, part, None)
            if callable(value) and not isinstance(value, QWidget):
                value = value()
        for widget in value if isinstance(value, (list, tuple)) else [value]:
            if isinstance(widget, QWidget) and widget.isVisible() and not widget.size().isEmpty():
                found.append(widget)
    return found


def global_rect(widget: QWidget) -> QRect:
    return QRect(widget.mapToGlobal(QPoint(0, 0)), widget.size())


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
        self.text.setAlignment(Qt.AlignmentFlag.AlignLeft | Qt.AlignmentFlag.AlignTop)
        self._placed = False  # placed once: from then on it stays where it is when it can
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
        layout.setSizeConstraint(QLayout.SizeConstraint.SetFixedSize)
        layout.addWidget(self.title)
        layout.addWidget(self.text, 1)
        layout.addLayout(buttons)
        self.next_button.setDefault(True)
        self.next_button.setFocus()
        self.fit_text()
        self.show_step(0)

    def fit_text(self) -> None:
        """One size for every step, the longest text's: nothing is clipped, and Next does
        not move from step to step (again when shown: a style may change the font)."""
        self.text.setFixedWidth(max(420, 60 * self.text.fontMetrics().averageCharWidth()))
        shown = self.text.text()
        heights = []
        for _, text, _ in STEPS:
            self.text.setText(text)
            heights.append(self.text.heightForWidth(self.text.width()))
        self.text.setText(shown)
        self.text.setMinimumHeight(max(heights))

    def showEvent(self, event) -> None:  # noqa: N802 (Qt override)
        self.fit_text()
        super().showEvent(event)

    def _next(self) -> None:
        if self.step + 1 < len(STEPS):
            self.show_step(self.step + 1)
        else:
            self.close()

    def show_step(self, step: int) -> None:
        self.step = max(0, min(step, len(STEPS) - 1))
        title, text, _targets = STEPS[self.step]
        self.title.setText(f"<b>{title}</b> ({self.step + 1} of {len(STEPS)})")
        self.text.setText(text)
        self.back_button.setEnabled(self.step > 0)
        self.next_button.setText("Done" if self.step == len(STEPS) - 1 else "Next")
        if self.isVisible():
            self.place()

    def targets(self) -> list[QWidget]:
        """The widgets the step on show describes."""
        window = self.parentWidget()
        return [] if window is None else target_widgets(window.window(), STEPS[self.step][2])

    def place(self) -> None:
        """Put the box inside the window where it covers least of the widgets this step
        describes, staying where it is when it covers none; on the screen in any case."""
        window = self.parentWidget()
        if window is None:
            return
        self.adjustSize()
        main = window.window()
        area, size = main.frameGeometry(), self.frameGeometry().size()
        central = main.centralWidget() if hasattr(main, "centralWidget") else None
        if central is not None:  # below the menus and the toolbar
            area.setTop(max(area.top(), central.mapToGlobal(QPoint(0, 0)).y() - MARGIN))
        screen = (window.screen() or QGuiApplication.primaryScreen()).availableGeometry()
        rects = [global_rect(w) for w in self.targets()]
        aim = area.center()
        if rects:
            union = rects[0]
            for r in rects[1:]:
                union = union.united(r)
            aim = union.center()
        w, h = size.width(), size.height()
        # the window's corners, edges and middle, and beside each widget described
        xs = {area.left() + MARGIN, area.center().x() - w // 2, area.right() - MARGIN - w}
        ys = {area.top() + MARGIN, area.center().y() - h // 2, area.bottom() - MARGIN - h}
        for r in rects:
            xs |= {r.left() - MARGIN - w, r.right() + MARGIN}
            ys |= {r.top() - MARGIN - h, r.bottom() + MARGIN}
        xs = sorted({min(max(x, area.left() + MARGIN), area.right() - MARGIN - w) for x in xs})
        ys = sorted({min(max(y, area.top() + MARGIN), area.bottom() - MARGIN - h) for y in ys})
        here = self.frameGeometry().topLeft() if self._placed else None
        candidates = ([here] if here is not None else []) + [QPoint(x, y) for y in ys for x in xs]

        def score(point: QPoint):
            box = QRect(self._on_screen(point, size, screen), size)
            covered = sum((box & r).width() * (box & r).height() for r in rects)
            return covered, point != here, (box.center() - aim).manhattanLength()

        best = min(candidates, key=score)
        self.move(self._on_screen(best, size, screen))
        self._placed = True

    @staticmethod
    def _on_screen(point: QPoint, size, screen: QRect) -> QPoint:
        x = min(max(point.x(), screen.left()), max(screen.left(), screen.right() + 1 - size.width()))
        y = min(max(point.y(), screen.top()), max(screen.top(), screen.bottom() + 1 - size.height()))
        return QPoint(x, y)


def start_tour(window, force: bool = False) -> Tour | None:
    """Show the tour (once per user unless ``force``); returns it, or None if already seen."""
    if not force and str(window.settings.value("tour/shown", "false")).lower() == "true":
        return None
    window.settings.setValue("tour/shown", "true")
    tour = Tour(window)
    tour.setAttribute(Qt.WidgetAttribute.WA_DeleteOnClose)
    tour.show()
    tour.place()
    return tour
