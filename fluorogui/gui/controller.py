"""The session controller: the Qt face of the workflow's ``Session``.

The ``Session`` (``fluorogui.workflow``) owns the project, its caches, every undoable
edit and the work; the command line and scripts use it exactly as the app does. This
adapter only adds what a desktop app needs on top:

* Qt signals for the session's events (``workflow.session.events.SessionEvent``: ``pose_changed``,
  ``outline_changed`` ...); frames
  are always frame numbers (the ``frame`` column of pairs.csv), never list positions;
* the GUI's own state: the frame on screen and the component being edited;
* ``dirty_changed`` for the window's modified flag, following ``session.history``'s
  listener events (the Undo / Redo actions follow the same history: ``actions.undo``);
* the project lock (``fluorogui.io.project.lock``) while a project file is open;
* ``apply_edit``, where the image panels' outline edits enter the session's history.

No geometry, matching or caching lives here.
"""
from __future__ import annotations

from pathlib import Path

from PySide6.QtCore import QObject, Signal

from fluorogui.core.records import Project
from fluorogui.io.errors import InputError
from fluorogui.io.project.lock import ProjectLock, ProjectLocked
from fluorogui.workflow.session import COMPONENT_ORDER, FrameState, Session
from fluorogui.workflow.session.events import SessionEvent
from fluorogui.workflow.session.history import Command

PROGRAM = "fluorogui (desktop)"

__all__ = ["FrameState", "PROGRAM", "SessionController"]


def _same_file(a: Path | None, b: Path | None) -> bool:
    if a is None or b is None:
        return False
    return Path(a).absolute() == Path(b).absolute()


class SessionController(QObject):
    """A ``Session`` with Qt signals, the current frame and component, and the project lock."""

    project_replaced = Signal()
    frame_changed = Signal(int)  # frame number
    component_changed = Signal(str)
    pose_changed = Signal(int, str)  # frame number, component
    outline_changed = Signal(object, str)  # (frame, view, component) key, component
    knee_changed = Signal(str)  # "side" or the component whose anatomical frame changed
    dirty_changed = Signal(bool)
    path_changed = Signal(object)
    model_changed = Signal(str)  # a component's mesh file was relinked

    def __init__(self, parent: QObject | None = None, session: Session | None = None) -> None:
        super().__init__(parent)
        self.session = session or Session()
        self.frame: int | None = None
        self.component = COMPONENT_ORDER[0]
        self.lock: ProjectLock | None = None
        self.read_only = False  # another program holds the file: save only to another one
        self._dirty = self.session.dirty
        # each session event as the signal that says it (PROJECT: set_project emits its own)
        self._handlers = {
            SessionEvent.POSE: lambda key: self.pose_changed.emit(int(key[0]), str(key[1])),
            SessionEvent.OUTLINE: lambda key: self.outline_changed.emit(tuple(key), str(key[2])),
            SessionEvent.KNEE: lambda what: self.knee_changed.emit(str(what)),
            SessionEvent.MODEL: lambda component: self.model_changed.emit(str(component)),
            SessionEvent.SAVED: lambda _path: self.path_changed.emit(self.session.path),
        }
        self.session.history.listeners.append(self._history_changed)
        self.session.listeners.append(self._session_event)

    # -- what the session says ---------------------------------------------------------------
    def _session_event(self, event: SessionEvent, what) -> None:
        handler = self._handlers.get(event)
        if handler is not None:
            handler(what)

    def _history_changed(self, _event: str, _entry) -> None:
        dirty = self.session.dirty
        if dirty != self._dirty:
            self._dirty = dirty
            self.dirty_changed.emit(dirty)

    # -- the open project ------------------------------------------------------------------------
    @property
    def project(self) -> Project:
        return self.session.project

    @property
    def path(self) -> Path | None:
        return self.session.path

    @property
    def dirty(self) -> bool:
        return self.session.dirty

    def set_project(self, project: Project, path=None, lock: ProjectLock | None = None,
                    read_only: bool = False) -> None:
        """Put another project on screen (after it loaded or was built); ``lock`` is the
        lock taken on ``path`` (the previous project's lock is released)."""
        if self.lock is not None and self.lock is not lock:
            self.lock.release()
        self.lock = lock
        self.read_only = bool(read_only)
        self.session.replace_project(project, path)
        frames = self.session.frames
        saved = project.settings.get("gui", {}) if isinstance(project.settings.get("gui"), dict) else {}
        frame = saved.get("frame")
        if frame not in frames and isinstance(saved.get("frame_index"), int) and \
                0 <= saved["frame_index"] < len(frames):  # files written before frame numbers
            frame = frames[saved["frame_index"]]
        self.frame = frame if frame in frames else (frames[0] if frames else None)
        names = self.session.components()
        if names and self.component not in names:
            self.component = names[0]
        self._dirty = self.session.dirty
        self.project_replaced.emit()
        self.path_changed.emit(self.path)
        self.dirty_changed.emit(self._dirty)
        if self.frame is not None:
            self.frame_changed.emit(self.frame)

    def open(self, path, read_only: bool = False) -> None:
        """Open a project file, taking its lock unless ``read_only``. Raises ProjectLocked
        when another live program holds it, InputError when it cannot be read; the open
        project is then left as it was."""
        path = Path(path)
        lock = None if read_only else ProjectLock(path, PROGRAM).acquire()
        try:
            opened = Session.open(path)
        except BaseException:
            if lock is not None:
                lock.release()
            raise
        self.set_project(opened.project, opened.path, lock=lock, read_only=read_only)

    def claim(self, path) -> str:
        """Make ``path`` the session's file (e.g. after recovering its autosave) and take
        its lock; returns "" or, when another program holds it, why it stays read-only."""
        path = Path(path)
        try:
            lock = ProjectLock(path, PROGRAM).acquire()
        except ProjectLocked as exc:
            self.session.path = path
            self.read_only = True
            self.path_changed.emit(path)
            return str(exc)
        if self.lock is not None:
            self.lock.release()
        self.lock, self.read_only = lock, False
        self.session.path = path
        self.path_changed.emit(path)
        return ""

    def save(self, path=None) -> None:
        """Save (atomically) to ``path`` or the session's file. Saving to another file
        takes that file's lock (ProjectLocked when another program holds it) and lets
        go of the old one; raises InputError or OSError when writing fails."""
        target = Path(path) if path else self.session.path
        if target is None:
            raise ValueError("no file name to save to")
        if self.read_only and _same_file(target, self.session.path):
            raise InputError(target, "is open read-only (another program holds it); save a copy with Save As")
        new_lock = None
        if self.lock is None or not _same_file(self.lock.project_path, target):
            new_lock = ProjectLock(target, PROGRAM).acquire()
        settings = self.session.project.settings
        gui = settings.get("gui") if isinstance(settings.get("gui"), dict) else {}
        gui.pop("frame_index", None)
        gui["frame"] = self.frame
        settings["gui"] = gui
        old_path = self.session.path
        try:
            self.session.save(target)
        except BaseException:
            if new_lock is not None:
                new_lock.release()
            raise
        if new_lock is not None:
            if self.lock is not None:
                self.lock.release()
            self.lock = new_lock
        self.read_only = False
        if not _same_file(old_path, target):
            self.path_changed.emit(self.session.path)

    def close(self) -> None:
        """Let go of the project file (the app is closing)."""
        if self.lock is not None:
            self.lock.release()
            self.lock = None

    # -- frame and component on screen -------------------------------------------------------------
    @property
    def frames(self) -> list[int]:
        return self.session.frames

    def components(self) -> list[str]:
        return self.session.components()

    @property
    def frame_index(self) -> int:
        """Position of the frame on screen in the project's frame list (for display)."""
        return self.session.index_of(self.frame) if self.frame is not None else 0

    def set_frame(self, frame: int) -> None:
        """Show frame number ``frame`` (ignored when the project has no such frame)."""
        if frame is None or not self.session.has_frame(int(frame)):
            return
        if int(frame) != self.frame:
            self.frame = int(frame)
            self.frame_changed.emit(self.frame)

    def step_frame(self, step: int) -> None:
        if self.frame is not None:
            self.set_frame(self.session.neighbour(self.frame, step))

    def set_component(self, component: str) -> None:
        if component != self.component:
            self.component = component
            self.component_changed.emit(component)

    def outline_key(self, view: int, component: str | None = None, frame: int | None = None):
        return (self.frame if frame is None else int(frame), int(view), component or self.component)

    # -- edits from the image panels -------------------------------------------------------------
    def apply_edit(self, text: str, outline=None, steps=()) -> None:
        """One undoable edit made in an image panel: ``outline`` = (key, points or None)
        goes to the session as a user's (reviewed) outline; ``steps`` are (do, undo)
        pairs of the panel's own display state (erased edges) kept in the same entry."""
        history = self.session.history
        history.begin_macro(text)
        try:
            for do, undo in steps:
                history.push(Command(text, None, False, True,
                                     lambda _key, on, _do=do, _undo=undo: _do() if on else _undo()))
            if outline is not None:
                key, points = outline
                self.session.set_outline(key, points, text)
        finally:
            history.end_macro()
