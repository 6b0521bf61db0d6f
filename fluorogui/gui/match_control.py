"""Running the long tasks from the main window: a match, tracking over frames and finding the
implants in the worker thread, with live overlays, and storing what comes back.

``MatchControl`` is a mixin of ``MainWindow``; it uses the window's controller, runner,
panels, matcher panel and 3D scene."""
from __future__ import annotations

import time

from fluorogui.core.session import MatchRecord
from fluorogui.gui import jobs
from fluorogui.io.errors import InputError

LIVE_3D_INTERVAL_S = 0.4  # the 3D model follows a live match at most this often
LIVE_3D_MAX_RENDER_S = 0.03  # and not at all where a render takes longer


class MatchControl:
    """Task handling of ``MainWindow`` (a mixin)."""

    # -- matching --------------------------------------------------------------------------
    def _inputs_or_warn(self, title: str):
        """(images, views, mesh of the active component) for a task, or None after telling the
        user why not (None without a word while another task runs)."""
        if self.runner.is_running():
            return None
        c = self.controller
        try:
            if c.frame is None or c.n_views() < 2 or c.component not in c.components():
                raise ValueError("open a session with two views and a model first")
            images = c.images()
            if any(image is None for image in images):
                raise ValueError("an image of this frame is missing")
            return images, c.project.views[:2], c.mesh(c.component)
        except (InputError, ValueError) as exc:
            self._warn(title, str(exc))
            return None

    def run_match(self) -> bool:
        """Match the active component in the current frame in the worker thread."""
        c = self.controller
        inputs = self._inputs_or_warn("Cannot match")
        if inputs is None:
            return False
        images, views, mesh = inputs
        self._live_component = c.component
        task = jobs.match_task(c.component, c.frame, images, views, mesh, c.pose(c.component),
                               self.matcher.settings(), c.splines(c.component))
        return self.runner.start(task, f"Matching the {c.component} component")

    def track_frames(self) -> bool:
        """Match the active component in this and every later frame, each from the last."""
        c = self.controller
        inputs = self._inputs_or_warn("Cannot track")
        if inputs is None:
            return False
        _, views, mesh = inputs
        frames = c.frames[c.frame_index:]
        paths = [[c.image_path(v, c.frame_index + k) for v in range(2)] for k in range(len(frames))]
        reviewed = {}
        for f in frames:
            records = [c.outline_record(c.outline_key(v, c.component, f)) for v in range(2)]
            if all(r is not None and r.reviewed for r in records):
                reviewed[f] = [r.points for r in records]
        self._live_component = c.component
        task = jobs.batch_task(c.component, frames, paths, views, mesh, c.pose(c.component),
                               self.matcher.settings(), reviewed)
        return self.runner.start(task, f"Tracking the {c.component} component")

    def find_implants(self) -> bool:
        """Locate every component in the current frame's images (global search, in the worker)."""
        c = self.controller
        inputs = self._inputs_or_warn("Cannot search")
        if inputs is None:
            return False
        images, views, _ = inputs
        try:
            meshes = {name: c.mesh(name) for name in c.components()}
        except InputError as exc:
            self._warn("Cannot search", str(exc))
            return False
        return self.runner.start(jobs.placement_task(images, views, meshes), "Finding the implants")

    def _running_changed(self, running: bool) -> None:
        self.matcher.set_running(running)
        self.cancel_action.setEnabled(running)
        for a in (self.run_action, self.track_action, self.find_action, self.open_action, self.import_action,
                  self.demo_action):
            a.setEnabled(not running)
        if running:
            self.statusBar().showMessage(self.runner.label + "…")

    def _task_progress(self, payload) -> None:
        if isinstance(payload, jobs.LiveUpdate):
            self.matcher.show_live(payload.calls, payload.objective_mm, payload.history)
            self._show_model_outline(payload.component, payload.pose, payload.outlines_px)
            now = time.perf_counter()
            if (self.scene_widget is not None and now - self._last_live_3d > LIVE_3D_INTERVAL_S
                    and not self.scene_widget.software_gl
                    and self.scene_widget.last_render_s < LIVE_3D_MAX_RENDER_S):
                # a 3D render costs more than a 2D overlay: follow less often, and not at all
                # where rendering is slow (software OpenGL); the result is shown at the end
                self._last_live_3d = now
                self.scene_widget.scene.set_pose(payload.component, payload.pose)
                self.scene_widget.scene.render()
        elif isinstance(payload, jobs.BatchProgress):
            self.matcher.show_batch(payload.done, payload.total, payload.seconds)
            self.statusBar().showMessage(f"{self.runner.label}: frame {payload.frame} done")
        elif isinstance(payload, str):
            self.statusBar().showMessage(payload)

    def _store_outcome(self, outcome: jobs.MatchOutcome) -> None:
        c = self.controller
        c.undo_stack.beginMacro(f"Match {outcome.component} in frame {outcome.frame}")
        self._deferred_overlay = True  # one overlay refresh (by the pose change) instead of one per outline
        try:
            if outcome.outlines_px is not None:
                for view, points in enumerate(outcome.outlines_px):
                    c.set_outline(c.outline_key(view, outcome.component, outcome.frame), points,
                                  text="Automatic outline", reviewed=False)
        finally:
            self._deferred_overlay = False
        c.set_pose(outcome.component, outcome.result.pose, frame=outcome.frame,
                   match=MatchRecord.from_result(outcome.result), text="Match")
        c.undo_stack.endMacro()

    def _task_item(self, payload) -> None:
        if isinstance(payload, jobs.MatchOutcome):
            self._store_outcome(payload)

    def _task_finished(self, result) -> None:
        c = self.controller
        if isinstance(result, jobs.MatchOutcome):
            self._store_outcome(result)
            self.matcher.show_result(MatchRecord.from_result(result.result), history=result.result.history)
            state = "converged" if result.result.converged else "did NOT converge - check the outlines"
            self.statusBar().showMessage(
                f"Matched the {result.component} component in {result.result.seconds:.2f} s: "
                f"objective {result.result.objective_mm:.3f} mm, {state}. Ctrl+Return accepts.", 15000)
        elif isinstance(result, jobs.BatchOutcome):
            n = len(result.frames_done)
            message = f"Tracked the {result.component} component through {n} frame(s)"
            if result.stopped_at is not None:
                message += f"; stopped at {result.reason}"
                if result.stopped_at in c.frames:
                    c.set_frame_index(c.frames.index(result.stopped_at))
            elif result.frames_done:
                c.set_frame_index(c.frames.index(result.frames_done[-1]))
            self.statusBar().showMessage(message, 20000)
        elif isinstance(result, jobs.PlacementOutcome):
            c.undo_stack.beginMacro("Find implants")
            for name, pose in result.poses.items():
                c.set_pose(name, pose, text=f"Find {name}")
            c.undo_stack.endMacro()
            found = ", ".join(f"{n} (overlap {100 * iou:.0f} %)" for n, iou in result.iou.items())
            self.statusBar().showMessage(f"Found {found}. Press F5 to match.", 15000)

    def _task_cancelled(self) -> None:
        latency = (time.perf_counter() - self.runner.cancel_requested_at) if self.runner.cancel_requested_at else None
        self.last_cancel_latency = latency
        if self._live_component is not None:
            self._show_pose(self._live_component)  # back to the stored pose
        self.matcher.show_result(None, label="Cancelled; the pose is unchanged")
        self.statusBar().showMessage("Cancelled; the pose is unchanged", 8000)

    def _task_failed(self, message: str) -> None:
        if self._live_component is not None:
            self._show_pose(self._live_component)
        self._warn("The task failed", message)
