"""Placeholder desktop app: a main window with two image panels and a File menu.

The real GUI (demo project, outline editing, 3D scene, matching) replaces this later.
"""
from __future__ import annotations

import sys
from pathlib import Path

from PySide6.QtCore import Qt, QTimer
from PySide6.QtGui import QAction, QColor, QKeySequence, QPainter, QPixmap
from PySide6.QtWidgets import (
    QApplication,
    QFileDialog,
    QHBoxLayout,
    QLabel,
    QMainWindow,
    QMessageBox,
    QSizePolicy,
    QWidget,
)

from fluorogui import __version__
from fluorogui.io.errors import InputError
from fluorogui.io.project import Project, load_project

PROJECT_FILE_FILTER = "fluorogui projects (*.fluoro);;All files (*)"
PLACEHOLDER_GREY = QColor(128, 128, 128)


class ImagePanel(QLabel):
    """One fluoroscopic view: for now a grey image with the view's title on it."""

    def __init__(self, title: str, parent: QWidget | None = None) -> None:
        super().__init__(parent)
        self.title = title
        self.setObjectName(title.replace(" ", "_").lower())
        self.setAccessibleName(title)
        self.setAlignment(Qt.AlignmentFlag.AlignCenter)
        self.setMinimumSize(320, 320)
        self.setSizePolicy(QSizePolicy.Policy.Ignored, QSizePolicy.Policy.Ignored)
        self._redraw()

    def _redraw(self) -> None:
        size = self.size()
        pixmap = QPixmap(max(size.width(), 1), max(size.height(), 1))
        pixmap.fill(PLACEHOLDER_GREY)
        painter = QPainter(pixmap)
        painter.setPen(Qt.GlobalColor.white)
        font = painter.font()
        font.setPointSize(18)
        painter.setFont(font)
        painter.drawText(pixmap.rect(), Qt.AlignmentFlag.AlignCenter, self.title)
        painter.end()
        self.setPixmap(pixmap)

    def resizeEvent(self, event) -> None:  # noqa: N802 (Qt override)
        super().resizeEvent(event)
        self._redraw()


class MainWindow(QMainWindow):
    """Top-level window: two image panels side by side, File menu, status bar."""

    def __init__(self, parent: QWidget | None = None) -> None:
        super().__init__(parent)
        self.setWindowTitle("fluorogui")
        self.project_path: Path | None = None
        self.project: Project | None = None

        self.image_panels = [ImagePanel("View 1"), ImagePanel("View 2")]
        central = QWidget()
        layout = QHBoxLayout(central)
        for panel in self.image_panels:
            layout.addWidget(panel)
        self.setCentralWidget(central)

        file_menu = self.menuBar().addMenu("&File")
        self.open_action = QAction("&Open…", self)
        self.open_action.setShortcut(QKeySequence.StandardKey.Open)
        self.open_action.triggered.connect(self.choose_and_open_project)
        file_menu.addAction(self.open_action)
        file_menu.addSeparator()
        self.quit_action = QAction("&Quit", self)
        self.quit_action.setShortcut(QKeySequence("Ctrl+Q"))
        self.quit_action.triggered.connect(self.close)
        file_menu.addAction(self.quit_action)

        self.statusBar().showMessage(f"fluorogui {__version__}: no project open")
        self.resize(1200, 700)

    def choose_and_open_project(self) -> None:
        path, _ = QFileDialog.getOpenFileName(self, "Open project", "", PROJECT_FILE_FILTER)
        if path:
            self.open_project(path)

    def open_project(self, path: str | Path) -> bool:
        """Open a project file; on failure warn the user and keep the current state."""
        try:
            project = load_project(path)
        except InputError as exc:
            QMessageBox.warning(self, "Cannot open project", str(exc))
            self.statusBar().showMessage(f"Could not open {path}")
            return False
        self.project_path = Path(path)
        self.project = project
        self.setWindowTitle(f"{self.project_path.name} — fluorogui")
        self.statusBar().showMessage(f"Opened {path}")
        return True


def run_app(path: str | Path | None = None) -> int:
    """Start the desktop app, optionally opening a project file; return the exit code."""
    app = QApplication.instance() or QApplication(sys.argv[:1])
    app.setApplicationName("fluorogui")
    app.setApplicationVersion(__version__)
    app.setDesktopFileName("fluorogui")
    window = MainWindow()
    window.show()
    if path is not None:
        QTimer.singleShot(0, lambda: window.open_project(path))
    return app.exec()
