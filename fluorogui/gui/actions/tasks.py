"""Running the workflow's jobs from the main window: match (the active component or both),
track the following frames (the active component or both) and find the implants, in the
worker thread with live overlays, progress and cancel; then storing what comes back
through the session and saying what happened in plain words.

``MatchControl`` is given the controller, the task runner, the matcher panel it drives
(the Matcher panel's buttons are its controls), the 3D scene, the ``SessionView`` that
draws live results, ``MissingFiles`` (a task that cannot start for a missing model offers
to locate it) and the ``Notices``. Its actions are declared in ``gui.layout.actions``. The
jobs come from ``Session.match_job`` / ``find_job`` / ``track_job`` (see ``jobs``): no
matching loop or tracking rule of its own.
"""
from __future__ import annotations

import time

from PySide6.QtCore import QObject, QTimer

from fluorogui.core.status import Status
from fluorogui.gui import jobs
from fluorogui.gui.eta import Eta, describe
from fluorogui.gui.notices import Notices
from fluorogui.gui.panels.matcher_panel import MatcherPanel
from fluorogui.gui.worker import TaskRunner
from fluorogui.io.errors import InputError
from fluorogui.workflow.messages import rim_note, view_count_note

LIVE_3D_INTERVAL_S = 0.4  # the 3D model follows a live match at most this often
LIVE_3D_MAX_RENDER_S = 0.03  # and not at all where a render takes longer


def frame_list(frames) -> str:
    """Frame numbers as short text: "1–3, 7, 9"."""
    frames = sorted(frames)
    parts, i = [], 0
    while i < len(frames):
        j = i
        while j + 1 < len(frames) and frames[j + 1] == frames[j] + 1:
            j += 1
        parts.append(str(frames[i]) if j == i else f"{frames[i]}{'–' if j > i + 1 else ', '}{frames[j]}")
        i = j + 1
    return ", ".join(parts)


class TrackSummary:
    """What a tracking run has done so far, frame by frame."""

    def __init__(self, frames, components) -> None:
        self.frames = list(frames)
        self.components = list(components)
        self.matched: list[int] = []
        self.review: list[int] = []
        self.failed: list[int] = []
        self.elapsed_s = 0.0

    def add(self, frame: int, results) -> None:
        status = jobs.frame_status(results)
        {Status.FAILED: self.failed, Status.NEEDS_REVIEW: self.review}.get(status, self.matched).append(frame)

    @property
    def done(self) -> int:
        return len(self.matched) + len(self.review) + len(self.failed)

    def counts(self) -> str:
        return (f"{len(self.matched)} matched, {len(self.review)} need{'s' if len(self.review) == 1 else ''} review, "
                f"{len(self.failed)} failed")

    def text(self, ending: str = "") -> str:
        what = " and ".join(self.components)
        head = (f"Tracked {what} through {self.done} of {len(self.frames)} frame"
                f"{'s' if len(self.frames) != 1 else ''}" + (f" ({frame_list(self.frames)})" if self.frames else "")
                + f" in {self.elapsed_s:.1f} s: {self.counts()}.")
        if self.review:
            head += f" Needs review: frame {frame_list(self.review)}."
        if self.failed:
            head += f" Failed: frame {frame_list(self.failed)}."
        return head + (f" {ending}" if ending else "")


class MatchControl(QObject):
    """The long tasks of a main window: starting them, following them, and their results."""

    def __init__(self, controller, runner: TaskRunner, matcher: MatcherPanel, scene_widget, session_view,
                 missing, notices: Notices) -> None:
        """``scene_widget``: the 3D scene (None without one); ``session_view``: a
        ``SessionView``; ``missing``: a ``MissingFiles``."""
        super().__init__(notices.parent_widget)
        self.controller = controller
        self.runner = runner
        self.matcher = matcher
        self.scene_widget = scene_widget
        self.session_view = session_view
        self.missing = missing
        self.notices = notices
        self.last_cancel_latency: float | None = None
        self._last_live_3d = 0.0
        self._live_components: list[str] = []
        self._task_kind = ""
        self._track: TrackSummary | None = None
        self._find_kept: list[str] = []  # matched components a find left alone
        self._find_replace = False  # ... or replaced, as the user confirmed
        self.last_track: TrackSummary | None = None  # the summary of the last tracking run that ended
        self._track_history: list[float] = []
        self._eta: Eta | None = None
        self._follow_frame: int | None = None
        self._follow_timer = QTimer(self)
        self._follow_timer.setSingleShot(True)
        self._follow_timer.setInterval(0)
        self._follow_timer.timeout.connect(self._follow)
        m = self.matcher
        m.run_requested.connect(lambda: self.run_match())
        m.run_both_requested.connect(lambda: self.match_both())
        m.cancel_requested.connect(runner.cancel)
        m.track_requested.connect(lambda: self.track_frames())
        m.track_both_requested.connect(lambda: self.track_both())
        m.place_requested.connect(lambda: self.find_implants())
        m.settings_edited.connect(self._settings_edited)
        runner.running_changed.connect(self._running_changed)
        runner.progress.connect(self._task_progress)
        runner.item.connect(self._task_item)
        runner.finished.connect(self._task_finished)
        runner.cancelled.connect(self._task_cancelled)
        runner.failed.connect(self._task_failed)

    # -- starting work -----------------------------------------------------------------------------
    def _ready(self, title: str, views: int = 1) -> bool:
        """Whether a task can start now (else the user is told why, or nothing while
        another task runs); ``views``: the fewest views it works with (a single-plane
        session matches and tracks, but finding implants needs two)."""
        if self.runner.is_running():
            return False
        c, s = self.controller, self.controller.session
        if c.frame is None or s.n_views < views or not s.components():
            need = "two views" if views >= 2 else "a calibrated view"
            self.notices.warn(title, f"Open a session with {need} and a model first.")
            return False
        return True

    def _settings_edited(self) -> None:
        """The matcher panel's method / density / outline points go into the session's
        settings, so the app and a script on the same project match alike."""
        s = self.controller.session
        settings = s.settings
        settings.match = self.matcher.settings(settings.match)
        s.set_settings(settings)

    def run_match(self, components=None) -> bool:
        """Match the active component (or ``components``, e.g. "both") in the frame on screen."""
        if not self._ready("Cannot match"):
            return False
        c, s = self.controller, self.controller.session
        names = s.components() if components in ("both", "all") else [components or c.component]
        todo = [n for n in names if not ((r := s.pose_record(n, c.frame)) is not None and r.reviewed)]
        if not todo:
            what = "poses are" if len(names) > 1 else f"{names[0]} pose is"
            self.notices.status(f"The {what} accepted in frame {c.frame}; Un-accept it "
                                "(Ctrl+Shift+Return) to match it again", 10000)
            return False
        try:
            job = s.match_job(c.frame, todo)
        except (InputError, KeyError, ValueError) as exc:
            self.missing.job_error("Cannot match", exc)
            return False
        self._live_components = todo
        self._task_kind = "match"
        skipped = [n for n in names if n not in todo]
        label = f"Matching {' and '.join(todo)} in frame {c.frame}" + (
            f" (the accepted {' and '.join(skipped)} pose is kept)" if skipped else "")
        return self.runner.start(jobs.match_task(job), label)

    def match_both(self) -> bool:
        return self.run_match("both")

    def track_frames(self, components=None) -> bool:
        """Track the active component (or "both") through the frames after the one on
        screen - from this frame itself when a component is not matched in it yet.
        Accepted poses are kept, others are matched again; a frame that fails its checks
        is flagged and tracking goes on."""
        if not self._ready("Cannot track"):
            return False
        c, s = self.controller, self.controller.session
        names = s.components() if components in ("both", "all") else [components or c.component]
        frames = s.frames
        here = s.index_of(c.frame)
        unmatched = any(not ((r := s.pose_record(n, c.frame)) is not None and r.is_matched) for n in names)
        todo = frames[here:] if unmatched else frames[here + 1:]
        if not todo:
            self.notices.status("This is the last frame: no frame follows it to track", 8000)
            return False
        try:
            job = s.track_job(frames=todo, components=names, redo=True)
        except (InputError, KeyError, ValueError) as exc:
            self.missing.job_error("Cannot track", exc)
            return False
        self._track = TrackSummary(todo, names)
        self._live_components = []
        self._task_kind = "track"
        self._eta = Eta(len(todo))
        self.matcher.show_batch(0, len(todo), 0.0)
        return self.runner.start(jobs.track_task(job), f"Tracking {' and '.join(names)} from frame {todo[0]}")

    def track_both(self) -> bool:
        return self.track_frames("both")

    def find_implants(self) -> bool:
        """Locate every component in the frame on screen (a global search, in the worker)."""
        if not self._ready("Cannot search", views=2):
            return False
        c, s = self.controller, self.controller.session
        matched = s.matched_in(c.frame)
        replace = bool(matched) and self.notices.ask(
            "Find implants", f"The {' and '.join(matched)} pose{'s are' if len(matched) > 1 else ' is'} matched or "
            f"accepted in frame {c.frame}. Find {'them' if len(matched) > 1 else 'it'} again and replace "
            f"{'their poses' if len(matched) > 1 else 'its pose'}?")
        if matched and not replace and len(matched) == len(s.components()):
            self.notices.status(f"Kept the matched poses of frame {c.frame}", 8000)
            return False
        try:
            job = s.find_job(c.frame, "both", replace=replace)
        except (InputError, KeyError, ValueError) as exc:
            self.missing.job_error("Cannot search", exc)
            return False
        self._find_kept = [] if replace else matched
        self._find_replace = replace
        self._live_components = []
        self._task_kind = "find"
        self._eta = Eta(1.0)
        self.matcher.show_progress(0.0, "Looking for the implants")
        return self.runner.start(jobs.find_task(job), f"Finding the implants in frame {c.frame}")

    # -- while it runs -------------------------------------------------------------------------------
    def cancel(self) -> None:
        """Stop the running task (it ends at its next check)."""
        self.runner.cancel()

    def _running_changed(self, running: bool) -> None:
        self.matcher.set_running(running)
        if running:
            self.matcher.show_summary("")
            self.notices.status(self.runner.label + "…")

    def _task_progress(self, payload) -> None:
        if isinstance(payload, jobs.LiveUpdate):
            if payload.component == self.controller.component or len(self._live_components) == 1:
                self.matcher.show_live(payload.calls, payload.objective_mm, payload.history)
            self.session_view.show_model_outline(payload.component, payload.pose, payload.outlines_px)
            now = time.perf_counter()
            if (self.scene_widget is not None and now - self._last_live_3d > LIVE_3D_INTERVAL_S
                    and not self.scene_widget.software_gl
                    and self.scene_widget.last_render_s < LIVE_3D_MAX_RENDER_S):
                # a 3D render costs more than a 2D overlay: follow less often, and not at all
                # where rendering is slow (software OpenGL); the result is shown at the end
                self._last_live_3d = now
                self.scene_widget.scene.set_pose(payload.component, payload.pose)
                self.scene_widget.scene.render()
        elif isinstance(payload, jobs.FindProgress):
            left = describe(self._eta.update(payload.fraction)) if self._eta is not None else ""
            text = f"{payload.text}, {left}" if left else payload.text
            self.matcher.show_progress(payload.fraction, text)
            self.notices.status(f"{self.runner.label}: {text} (Esc cancels)")

    def _store(self, results, text: str | None = None) -> None:
        """Results into the session (one undoable step), with one overlay refresh."""
        with self.session_view.one_overlay_refresh():
            self.controller.session.store(results, text)

    def _task_item(self, payload) -> None:
        if not isinstance(payload, jobs.TrackedFrame) or self._track is None:
            return
        self._store(payload.results, f"Track frame {payload.frame}")
        self._track.add(payload.frame, payload.results)
        self._track.elapsed_s = payload.elapsed_s
        left = self._eta.update(payload.done) if self._eta is not None else None
        self.matcher.show_batch(payload.done, payload.total, payload.elapsed_s, left)
        self._follow_frame = payload.frame  # the view follows, at most once per event-loop pass
        self._follow_timer.start()
        shown = next((r for r in payload.results if r.component == self.controller.component), payload.results[0])
        self._track_history = shown.match.history if shown.match is not None else []
        following = f"; now frame {payload.next_frame}" if payload.next_frame is not None else ""
        self.notices.status(f"{self.runner.label}: frame {payload.frame} done ({payload.done}/"
                            f"{payload.total}{following}) — {self._track.counts()}")

    def _follow(self) -> None:
        frame, self._follow_frame = self._follow_frame, None
        if frame is None:
            return
        self.matcher.plot.set_values(self._track_history)  # that frame's objective
        self.controller.set_frame(frame)

    def _task_finished(self, result) -> None:
        s = self.controller.session
        if self._task_kind == "match":  # the frame's results, one per component
            self._store(result)
            self.show_results(result)
        elif self._task_kind == "track":
            self._end_tracking()
        elif self._task_kind == "find":  # the placements by component
            s.store_placements(result, replace=self._find_replace)
            found = [p for p in result.values() if p.found]
            text = "; ".join([p.describe() for p in result.values()]
                             + [f"kept the matched {name} pose" for name in self._find_kept])
            frame = next(iter(result.values())).frame if result else self.controller.frame
            text = f"Find implants in frame {frame}: {text}." + (
                " Press Ctrl+F5 to match both." if found else " Place the models by hand (Place model, C).")
            self.matcher.show_summary(text)
            self.notices.status(text, 20000)
        self._live_components = []

    def show_results(self, results) -> None:
        """A finished match in plain words: status and reason of every component."""
        c = self.controller
        shown = next((r for r in results if r.component == c.component), results[0] if results else None)
        if shown is not None and shown.match is not None:
            self.matcher.plot.set_values(shown.match.history)
        self.session_view.show_pose_status()
        parts = []
        for r in results:
            took = f" in {r.seconds:.1f} s" if r.seconds else ""
            if r.status == Status.NEEDS_REVIEW:
                parts.append(f"{r.component} needs review{took}: {r.reason}")
            elif r.status == Status.FAILED:
                parts.append(f"{r.component} failed: {r.reason}")
            else:
                objective = f", objective {r.match.objective_mm:.3f} mm" if r.match is not None else ""
                rim = rim_note(r.match.settings) if r.match is not None else ""
                parts.append(f"{r.component} matched{took}{objective}" + (f" ({rim})" if rim else ""))
        flagged = any(r.status != Status.MATCHED for r in results)
        advice = (" Check the outlines and match again (F5), or accept the pose as it is (Ctrl+Return)."
                  if flagged else " Ctrl+Return accepts.")
        text = f"Frame {results[0].frame if results else c.frame}: " + "; ".join(parts) + "." + advice
        note = view_count_note(c.session.n_views)
        if note:
            text += f" Note: {note}."
        self.matcher.show_summary(text)
        self.notices.status(text, 20000)

    def _end_tracking(self, ending: str = "") -> None:
        track, self._track = self._track, None
        if track is not None:
            self.last_track = track
        self._follow_timer.stop()
        if self._follow_frame is not None:
            self._follow()
        if track is None:
            return
        flagged = sorted(track.review + track.failed)
        if flagged and not ending:
            ending = f"Showing frame {flagged[0]}, the first to review."
            self.controller.set_frame(flagged[0])
        text = track.text(ending)
        self.matcher.show_summary(text)
        self.notices.status(text, 30000)

    def _task_cancelled(self) -> None:
        latency = (time.perf_counter() - self.runner.cancel_requested_at) if self.runner.cancel_requested_at else None
        self.last_cancel_latency = latency
        for name in self._live_components:
            self.session_view.show_pose(name)  # back to the stored pose
        self._live_components = []
        if self._task_kind == "track":
            self._end_tracking("Cancelled: the frames tracked so far are kept (Ctrl+Z undoes them frame by frame); "
                               "the frame in progress is unchanged.")
            return
        text = ("Find implants cancelled; nothing changed" if self._task_kind == "find"
                else "Cancelled; the poses are unchanged")
        self.matcher.show_message(text)
        self.matcher.show_summary(text)
        self.notices.status(text, 8000)

    def _task_failed(self, message: str) -> None:
        for name in self._live_components:
            self.session_view.show_pose(name)
        self._live_components = []
        if self._task_kind == "track":
            self._end_tracking(f"Stopped: {message}")
        self.notices.warn("The task failed", message)
