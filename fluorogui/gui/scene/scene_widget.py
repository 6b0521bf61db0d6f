"""The 3D panel: a ``FluoroScene`` in a ``QtInteractor`` where the display has hardware
OpenGL, otherwise in an off-screen plotter whose frames are shown in a ``QLabel`` with mouse
rotate / pan / zoom (the Qt offscreen platform, and software OpenGL, where an embedded
OpenGL widget would make Qt composite the whole window in software), with camera buttons."""
from __future__ import annotations

import os
import time

import numpy as np
import pyvista as pv
from PySide6.QtCore import Qt, QTimer, Signal
from PySide6.QtGui import QGuiApplication, QImage, QPixmap
from PySide6.QtWidgets import QHBoxLayout, QLabel, QSizePolicy, QToolButton, QVBoxLayout, QWidget

from fluorogui.gui.scene.scene3d import FluoroScene

NO_GL_PLATFORMS = {"offscreen", "minimal"}
SOFTWARE_GL = ("llvmpipe", "softpipe", "swrast", "software rasterizer", "swiftshader")


def opengl_available() -> bool:
    """Whether a QtInteractor can get an OpenGL context on this Qt platform."""
    if os.environ.get("FLUOROGUI_NO_GL", "") not in ("", "0"):
        return False
    return QGuiApplication.platformName() not in NO_GL_PLATFORMS


def gl_renderer() -> str:
    """The OpenGL renderer string of this display ("" when there is no context)."""
    from PySide6.QtGui import QOffscreenSurface, QOpenGLContext

    context = QOpenGLContext()
    if not context.create():
        return ""
    surface = QOffscreenSurface()
    surface.setFormat(context.format())
    surface.create()
    try:
        if not context.makeCurrent(surface):
            return ""
        return str(context.functions().glGetString(0x1F01) or "")  # GL_RENDERER
    finally:
        context.doneCurrent()


def interactive_view_advised() -> bool:
    """Whether to embed the interactive OpenGL view. Not with software OpenGL (llvmpipe,
    typical of VMs and remote desktops): Qt then composites the whole window through it,
    so every 2D repaint also costs a software 3D frame (60-90 ms stalls while matching).
    ``FLUOROGUI_GL=interactive`` forces the interactive view, ``=image`` the image view."""
    choice = os.environ.get("FLUOROGUI_GL", "").lower()
    if choice in ("image", "fallback"):
        return False
    if not opengl_available():
        return False
    if choice == "interactive":
        return True
    renderer = gl_renderer().lower()
    return bool(renderer) and not any(word in renderer for word in SOFTWARE_GL)


class _ImageView(QLabel):
    """Fallback display: shows screenshots, turns mouse drags / wheel into camera moves."""

    def __init__(self, owner: "Scene3DWidget"):
        super().__init__(owner)
        self._owner = owner
        self._last = None
        self.setAlignment(Qt.AlignmentFlag.AlignCenter)
        self.setSizePolicy(QSizePolicy.Policy.Ignored, QSizePolicy.Policy.Ignored)
        self.setMinimumSize(160, 120)  # the dock may be small on a laptop screen
        self.setStyleSheet("background: #0d0d12;")

    def mousePressEvent(self, event):  # noqa: N802
        self._last = event.position()
        event.accept()

    def mouseMoveEvent(self, event):  # noqa: N802
        if self._last is None:
            return
        pos = event.position()
        dx, dy = pos.x() - self._last.x(), pos.y() - self._last.y()
        self._last = pos
        cam = self._owner.plotter.camera
        if event.buttons() & (Qt.MouseButton.MiddleButton | Qt.MouseButton.RightButton):
            # pan in the view plane
            size = max(self.height(), 1)
            dist = cam.distance
            scale = 2 * dist * np.tan(np.radians(cam.view_angle) / 2) / size
            forward = np.subtract(cam.focal_point, cam.position)
            forward /= np.linalg.norm(forward)
            up = np.asarray(cam.up)
            right = np.cross(forward, up)
            shift = (-dx * right + dy * up) * scale
            cam.position = tuple(np.add(cam.position, shift))
            cam.focal_point = tuple(np.add(cam.focal_point, shift))
        else:
            cam.Azimuth(-dx * 0.4)
            cam.Elevation(dy * 0.4)
            cam.OrthogonalizeViewUp()
        self._owner.plotter.renderer.reset_camera_clipping_range()
        self._owner.request_render()
        event.accept()

    def mouseReleaseEvent(self, event):  # noqa: N802
        self._last = None
        event.accept()

    def wheelEvent(self, event):  # noqa: N802
        steps = event.angleDelta().y() / 120.0
        self._owner.plotter.camera.Zoom(1.1**steps)
        self._owner.plotter.renderer.reset_camera_clipping_range()
        self._owner.request_render()
        event.accept()

    def resizeEvent(self, event):  # noqa: N802
        super().resizeEvent(event)
        self._owner._fallback_resized(self.width(), self.height())


class Scene3DWidget(QWidget):
    """The 3D panel: camera buttons, a Rays toggle and the scene (interactive or fallback)."""

    pose_dragged = Signal(str, object)

    def __init__(self, parent: QWidget | None = None, *, window_size=(800, 600), interactive: bool | None = None,
                 multi_samples: int | None = None):
        """``multi_samples``: MSAA samples; by default pyvista's (4) when interactive, dropped to 0
        on a software GL, and 0 in the fallback (usually software, where MSAA costs ~2-3x)."""
        super().__init__(parent)
        self.interactive = interactive_view_advised() if interactive is None else bool(interactive)
        self._msaa_auto = self.interactive and multi_samples is None
        self._closed = False
        self.software_gl = not self.interactive  # the fallback renders off-screen, usually in software
        self.last_render_s = 0.0  # duration of the latest render (the app skips live 3D when slow)
        self._timer = QTimer(self)
        self._timer.setSingleShot(True)
        self._timer.setInterval(0)
        self._timer.timeout.connect(self._do_render)

        layout = QVBoxLayout(self)
        layout.setContentsMargins(0, 0, 0, 0)
        layout.setSpacing(2)
        bar = QHBoxLayout()
        bar.setContentsMargins(4, 2, 4, 0)
        self.buttons: dict[str, QToolButton] = {}
        for key, text in (("implant", "Implants"), ("view1", "View 1"), ("view2", "View 2"), ("top", "Top"),
                          ("iso", "Iso")):
            button = QToolButton(self)
            button.setText(text)
            button.setObjectName(f"camera_{key}")
            button.setToolTip(f"Camera: {text}")
            button.clicked.connect(lambda _=False, k=key: self.camera_preset(k))
            bar.addWidget(button)
            self.buttons[key] = button
        self.rays_button = QToolButton(self)
        self.rays_button.setText("Rays")
        self.rays_button.setObjectName("rays_toggle")
        self.rays_button.setCheckable(True)
        self.rays_button.setChecked(True)
        self.rays_button.setToolTip("Show rays from the sources through the outlines")
        self.rays_button.toggled.connect(self._rays_toggled)
        bar.addWidget(self.rays_button)
        bar.addStretch(1)
        layout.addLayout(bar)

        if self.interactive:
            from pyvistaqt import QtInteractor

            self.plotter = QtInteractor(self, auto_update=False, multi_samples=multi_samples)
            self.plotter.setSizePolicy(QSizePolicy.Policy.Expanding, QSizePolicy.Policy.Expanding)
            layout.addWidget(self.plotter, 1)
            self._label = None
        else:
            self.plotter = pv.Plotter(off_screen=True, window_size=list(window_size))
            self.plotter.render_window.SetMultiSamples(0 if multi_samples is None else int(multi_samples))
            self._label = _ImageView(self)
            layout.addWidget(self._label, 1)
        self.scene = FluoroScene(self.plotter)
        self.scene.render_callback = self.request_render

    # -- public ---------------------------------------------------------------------------
    def request_render(self) -> None:
        if not self._closed:
            self._timer.start()

    def set_views(self, views) -> None:
        """The session's views into the scene; a camera button only for a view it has."""
        self.scene.set_views(views)
        for key, button in self.buttons.items():
            if key.startswith("view"):
                button.setVisible(int(key[4:]) <= len(views))

    def camera_preset(self, name: str) -> None:
        if name.startswith("view") and int(name[4:]) > len(self.scene.views):
            return
        self.scene.camera_preset(name)

    def enable_gizmo(self, component: str) -> bool:
        return self.scene.enable_gizmo(component, lambda c, p: self.pose_dragged.emit(c, p))

    def grab_image(self) -> np.ndarray:
        """RGB (h, w, 3) uint8 screenshot of the scene."""
        if self._closed:
            raise RuntimeError("the 3D panel is closed")
        self._timer.stop()
        image = self._render_now()
        if not self.interactive:
            self._show(image)
        return np.ascontiguousarray(image[..., :3])

    def _check_software_gl(self) -> None:
        # once, after the first frame: a software GL (llvmpipe, Xvfb) pays ~2x per frame for MSAA
        if self._msaa_auto:
            self._msaa_auto = False
            try:
                caps = self.plotter.render_window.ReportCapabilities() or ""
            except Exception:  # noqa: BLE001 - a diagnostics call; never fatal
                caps = ""
            if any(word in caps.lower() for word in SOFTWARE_GL):
                self.software_gl = True
                self.plotter.render_window.SetMultiSamples(0)

    def _render_now(self) -> np.ndarray:
        """Render synchronously and read the frame back."""
        if self.plotter._first_time:  # before the first frame screenshot() renders by itself
            return self.plotter.screenshot(return_img=True)
        if self.interactive:
            self.plotter._render()
            self._check_software_gl()
        else:
            self.plotter.render()
        return self.plotter.screenshot(return_img=True)  # reads the frame, never re-renders

    # -- rendering -------------------------------------------------------------------------
    def _do_render(self) -> None:
        if self._closed:
            return
        t0 = time.perf_counter()
        if self.interactive:
            self.plotter._render()
            self._check_software_gl()
        else:
            self._show(self._render_now())
        self.last_render_s = time.perf_counter() - t0

    def _show(self, image: np.ndarray) -> None:
        image = np.ascontiguousarray(image[..., :3])
        h, w = image.shape[:2]
        qimage = QImage(image.data, w, h, 3 * w, QImage.Format.Format_RGB888).copy()
        self._label.setPixmap(QPixmap.fromImage(qimage))

    def _fallback_resized(self, w: int, h: int) -> None:
        if self._closed or w < 2 or h < 2:
            return
        if tuple(self.plotter.window_size) != (w, h):
            self.plotter.window_size = [w, h]
        self.request_render()

    def _rays_toggled(self, on: bool) -> None:
        self.scene.set_rays_visible(on)

    # -- closing ----------------------------------------------------------------------------
    def close(self) -> bool:  # noqa: D102
        self._shutdown()
        return super().close()

    def closeEvent(self, event):  # noqa: N802
        self._shutdown()
        super().closeEvent(event)

    def _shutdown(self) -> None:
        if self._closed:
            return
        self._closed = True
        self._timer.stop()
        self.scene.close()
        self.plotter.close()
