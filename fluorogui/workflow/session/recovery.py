"""Crash recovery of a session's unsaved work, kept as it happens.

A ``RecoveryJournal`` follows a session (its listeners) and keeps its unsaved state in a
recovery file of its own (the desktop app's ``recovery/autosave.fluoro``): the whole
project is written there once, at the first change after the session was opened or
saved, and from then on every change of the undo history (an edit, a tracked frame, a
find, an undo) appends the pose and outline records it touched to that file's journal
(``io.project.journal``: one line, flushed to disk, a frame of tracking costs one line).
Opening the recovery file merges the journal, so a crash loses at most the change in
progress: before, the app wrote the recovery file every three minutes, and a crash in a
one-minute *Track both* brought back only the import. Changes the journal does not
describe (the knee's side and anatomical frames, a relinked model, a removed record) write
the whole file again. Qt-free: the app owns one, a script may too.
"""
from __future__ import annotations

import json
import time
from pathlib import Path
from typing import Callable

from fluorogui.io.errors import InputError
from fluorogui.io.project import journal
from fluorogui.io.project.document import journal_frames, save_project
from fluorogui.workflow.session.events import HistoryEvent, SessionEvent

#: history events that end a change (its records are journalled then, in one line)
_CHANGE_ENDS = frozenset({HistoryEvent.PUSH, HistoryEvent.MERGE, HistoryEvent.UNDO, HistoryEvent.REDO})
#: session events the journal cannot describe: the whole file is written again
_WHOLE_FILE = frozenset({SessionEvent.KNEE, SessionEvent.MODEL})


class RecoveryJournal:
    """Keeps ``session``'s unsaved work in ``path`` (and its journal) as it changes.

    Parameters
    ----------
    session : fluorogui.workflow.session.Session
    path : path-like or callable
        The recovery file (a project file of the session's own), or ``path() -> Path``
        read at each write (the app's data folder may change while it runs).
    origin : callable, optional
        ``origin() -> str``: the project file the session came from, written beside the
        recovery file (``NAME.json``) so a recovery can say what it recovers.
    failed : callable, optional
        ``failed(error)`` when the file cannot be written (an ``InputError`` naming it): the
        edit itself goes on.
    """

    @property
    def path(self) -> Path:
        return Path(self._path() if callable(self._path) else self._path)

    def __init__(self, session, path, origin: Callable[[], str] | None = None,
                 failed: Callable[[Exception], None] | None = None) -> None:
        self.session = session
        self._path = path
        self.origin = origin or (lambda: "")
        self.failed = failed
        self.enabled = True
        self._written = False  # the file holds this session's project: journal lines add to it
        self._whole = False  # the next change writes the whole file
        self._poses: set = set()
        self._records: set = set()
        self._settings: str | None = None
        session.listeners.append(self._session_event)
        session.history.listeners.append(self._history_event)

    def close(self) -> None:
        """Stop following the session."""
        if self._session_event in self.session.listeners:
            self.session.listeners.remove(self._session_event)
        if self._history_event in self.session.history.listeners:
            self.session.history.listeners.remove(self._history_event)

    # -- what the session says ----------------------------------------------------------------
    def _session_event(self, event: str, what) -> None:
        if event in (SessionEvent.PROJECT, SessionEvent.SAVED):  # a new start: the next change writes the whole file
            self._written = False
            self._poses.clear()
            self._records.clear()
        elif event == SessionEvent.POSE:
            self._poses.add(tuple(what))
        elif event == SessionEvent.OUTLINE:
            self._records.add(tuple(what))
        elif event in _WHOLE_FILE:
            self._whole = True

    def _history_event(self, event: str, _entry) -> None:
        if event not in _CHANGE_ENDS:
            return
        try:
            self.keep()
        except (InputError, OSError) as exc:  # a full disk must not stop the edit
            self._whole = True  # what this change touched is written with the next one
            if self.failed is not None:
                self.failed(exc)

    # -- writing ---------------------------------------------------------------------------------
    def keep(self) -> None:
        """Write what changed since the last call: a journal line, or the whole file.
        Raises InputError (naming the file) when it cannot be written."""
        if not self.enabled or not self.session.project.views:
            return
        project = self.session.project
        poses, records = sorted(self._poses, key=str), sorted(self._records, key=str)
        self._poses.clear()
        self._records.clear()
        removed = any(k not in project.poses for k in poses) or any(k not in project.records for k in records)
        settings = json.dumps(project.settings, sort_keys=True, default=str)
        if not self._written or self._whole or removed:
            self.write_whole()
            return
        if not poses and not records and settings == self._settings:
            return
        journal_frames(project, self.path, poses, records, settings=settings != self._settings)
        self._settings = settings

    def write_whole(self) -> None:
        """Write the whole project to the recovery file (its journal is emptied)."""
        self.path.parent.mkdir(parents=True, exist_ok=True)
        save_project(self.session.project, self.path)
        self.path.with_suffix(".json").write_text(json.dumps({"origin": self.origin(), "time": time.time()}))
        self._settings = json.dumps(self.session.project.settings, sort_keys=True, default=str)
        self._written, self._whole = True, False

    def discard(self) -> None:
        """Delete the recovery file and its journal (the work was saved, or closed on purpose)."""
        self.path.unlink(missing_ok=True)
        journal.discard(self.path)
        self._written = False
