"""The 3D scene: X-ray sources, intensifier planes with their images, beams, implant models,
and on demand the condyles' contact points on the tray.

``FluoroScene`` builds everything on any pyvista ``Plotter`` (tests pass
``pv.Plotter(off_screen=True)``, the app passes a ``QtInteractor``). Updates reuse the
existing actors and data objects: a frame switch only rewrites texture buffers, a pose
change only sets an actor's user matrix.

The Qt panel that holds it is ``scene_widget.Scene3DWidget``.

Texture orientation: the plane quad's corners are the outer edges of the image's corner
pixels (``pixel_to_plane`` of (-0.5, -0.5) etc.) and the texture is filled row-major, so
texture ``t = 0`` is image row 0 and lies on the view's ``v = 0`` side: a pixel's texel sits
exactly where ``View.pixel_to_plane`` puts the pixel.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import pyvista as pv
from vtkmodules.util import numpy_support
from vtkmodules.vtkRenderingCore import vtkBillboardTextActor3D

from fluorogui.core.projection.geometry import View, closest_point_between_rays
from fluorogui.core.projection.pose import matrix_to_pose, pose_to_matrix

VIEW_COLOURS = [(1.0, 0.55, 0.15), (0.25, 0.65, 1.0), (0.85, 0.35, 0.85), (0.4, 0.85, 0.4)]
MODEL_COLOURS = {"femoral": (0.78, 0.84, 0.93), "tibial": (0.62, 0.86, 0.52)}
FALLBACK_MODEL_COLOUR = (0.9, 0.8, 0.55)
#: the condyles' points: colours that neither model (blue or grey femur, green tray) has
CONTACT_COLOURS = {"medial": (1.0, 0.2, 0.8), "lateral": (1.0, 0.85, 0.1)}
BACKGROUND_TOP = (0.16, 0.18, 0.22)
BACKGROUND_BOTTOM = (0.05, 0.05, 0.07)
DEFAULT_PERCENTILES = (0.5, 99.5)
CAMERA_PRESETS = ("view1", "view2", "top", "iso", "implant")


def window_image(image: np.ndarray, window=None, out: np.ndarray | None = None) -> np.ndarray:
    """Grey image of any dtype to uint8 through a (low, high) window; percentiles by default."""
    img = np.asarray(image)
    if img.ndim == 3:  # colour: use the mean of the channels
        img = img[..., :3].mean(axis=2)
    if window is None:
        step = max(1, int(np.sqrt(img.size / 65536)))  # percentiles of a ~64k-pixel sample
        sample = np.asarray(img[::step, ::step], dtype=np.float32)
        sample = sample[np.isfinite(sample)]
        lo, hi = np.percentile(sample, DEFAULT_PERCENTILES) if sample.size else (0.0, 1.0)
    else:
        lo, hi = (float(w) for w in window)
    if not hi > lo:
        hi = lo + 1.0
    scale = np.float32(255.0 / (hi - lo))
    work = np.subtract(img, np.float32(lo), dtype=np.float32)
    work *= scale
    work += np.float32(0.5)  # round on the cast below
    np.clip(work, 0.0, 255.0, out=work)
    if out is None:
        out = np.empty(img.shape, dtype=np.uint8)
    np.copyto(out, work, casting="unsafe")
    return out


@dataclass
class _ViewActors:
    """Everything drawn for one view and the buffers updated in place."""

    view: View
    colour: tuple
    source: object = None
    plane: object = None
    frustum: object = None
    label: object = None
    rays: object = None
    rays_mesh: pv.PolyData | None = None
    image_data: pv.ImageData | None = None
    buffer: np.ndarray | None = None  # uint8 (h, w) shared with the VTK texture
    texture: pv.Texture | None = None


class FluoroScene:
    """Scene-building on any pyvista Plotter (see the module docstring)."""

    def __init__(self, plotter: pv.Plotter):
        self.plotter = plotter
        self.views: list[View] = []
        self.display_views: list[View] = []  # as drawn (see set_views)
        self._view_actors: list[_ViewActors] = []
        self._models: dict[str, object] = {}  # component -> actor
        self._poses: dict[str, np.ndarray] = {}
        self._rays_visible = True
        self._contact = None  # the contact points' actor
        self._gizmo = None
        self._gizmo_component: str | None = None
        self._gizmo_callback = None
        self._gizmo_observer = None
        #: called by render() instead of plotter.render() when set (the widget coalesces)
        self.render_callback = None
        plotter.set_background(BACKGROUND_BOTTOM, top=BACKGROUND_TOP)
        self._light_kit()

    def _light_kit(self) -> None:
        # VTK's light kit (key, fill, back, head lights) keeps the metal readable from any side
        self.plotter.enable_lightkit()

    # -- views ------------------------------------------------------------------------------
    def set_views(self, views: list[View], plane_depth: str = "auto") -> None:
        """Draw each view's source, intensifier plane (textured quad), beam and label.

        Planes sit at the calibration's position and size. Only when a calibration had no
        pixel pitch (``view.extra["pitch_assumed"]``, e.g. MayaCam), where the plane depth
        is arbitrary, does ``plane_depth="auto"`` move that plane further along its beam
        (same projection) so it lies behind the subject and clear of the other planes;
        ``plane_depth="calibration"`` keeps it as read.
        """
        for va in self._view_actors:
            for actor in (va.source, va.plane, va.frustum, va.label, va.rays):
                if actor is not None:
                    self.plotter.remove_actor(actor, render=False)
        self.views = list(views)
        self.display_views = [self._display_view(v, plane_depth) for v in self.views]
        self._view_actors = []
        up = self._world_up()
        for k, view in enumerate(self.display_views):
            colour = VIEW_COLOURS[k % len(VIEW_COLOURS)]
            va = _ViewActors(view=view, colour=colour)
            size = 0.012 * view.distance
            sphere = pv.Sphere(radius=size, center=view.source, theta_resolution=24, phi_resolution=16)
            va.source = self.plotter.add_mesh(sphere, color=colour, smooth_shading=True, name=f"source{k}",
                                              render=False, reset_camera=False)
            va.source.prop.culling = "back"  # invisible when the camera sits inside it (view presets)

            corners = self._plane_corners(view)
            quad = pv.PolyData(corners, faces=np.array([4, 0, 1, 2, 3]))
            # texture t = 0 is image row 0 (v = -0.5 edge), s = 0 column 0
            quad.active_texture_coordinates = np.array([[0, 0], [1, 0], [1, 1], [0, 1]], dtype=np.float32)
            w, h = view.image_size
            va.image_data, va.buffer = self._new_image_data(w, h)
            va.buffer[:] = 40
            va.texture = pv.Texture(va.image_data)
            va.texture.interpolate = True
            va.texture.mipmap = True
            va.plane = self.plotter.add_mesh(quad, texture=va.texture, lighting=False, name=f"plane{k}",
                                             render=False, reset_camera=False)

            va.frustum = self.plotter.add_mesh(self._frustum_mesh(view, corners), color=colour, line_width=1.5,
                                               lighting=False, name=f"frustum{k}", render=False, reset_camera=False)
            va.label = self._label_actor(f"View {k + 1}", view.source + 2.5 * size * up, colour)
            self.plotter.add_actor(va.label, name=f"label{k}", reset_camera=False, render=False)
            va.rays_mesh = pv.PolyData()
            va.rays_mesh.points = view.source[None, :]  # one point, no cells: draws nothing
            va.rays = self.plotter.add_mesh(va.rays_mesh, color=colour, line_width=1.0, opacity=0.7,
                                            lighting=False, name=f"rays{k}", render=False, reset_camera=False)
            va.rays.visibility = self._rays_visible
            self._view_actors.append(va)
        self.render()

    @staticmethod
    def _label_actor(text: str, position, colour):
        # a billboard text: cheaper to render than pyvista's point-label placement mapper
        actor = vtkBillboardTextActor3D()
        actor.SetInput(text)
        actor.SetPosition(*np.asarray(position, dtype=float))
        prop = actor.GetTextProperty()
        prop.SetFontSize(16)
        prop.SetColor(*colour)
        prop.SetBold(True)
        prop.SetJustificationToCentered()
        return actor

    def _display_view(self, view: View, plane_depth: str) -> View:
        """The view drawn: the calibration's, or one with its plane pushed back (see set_views)."""
        if plane_depth not in ("auto", "calibration"):
            raise ValueError("plane_depth must be 'auto' or 'calibration'")
        if plane_depth == "calibration" or not view.extra.get("pitch_assumed") or len(self.views) < 2:
            return view
        subject_depth = float((self._target() - view.source) @ view.normal)
        w, h = view.image_size
        half_per_depth = np.hypot(w * view.pitch[0], h * view.pitch[1]) / 2 / view.distance
        if subject_depth <= 0 or half_per_depth >= 0.6:
            return view
        # the plane's half diagonal must stay short of the gap behind the subject
        depth = subject_depth / (1.0 - 1.3 * half_per_depth)
        if depth <= view.distance:
            return view
        scale = depth / view.distance
        return View(view.source, view.normal, view.e_u, view.e_v, view.distance * scale,
                    (view.pitch[0] * scale, view.pitch[1] * scale), view.principal_point, view.image_size,
                    name=view.name, extra={**view.extra, "display_scale": scale})

    @staticmethod
    def _plane_corners(view: View) -> np.ndarray:
        w, h = view.image_size
        uv = np.array([[-0.5, -0.5], [w - 0.5, -0.5], [w - 0.5, h - 0.5], [-0.5, h - 0.5]])
        return view.pixel_to_plane(uv)

    @staticmethod
    def _frustum_mesh(view: View, corners: np.ndarray) -> pv.PolyData:
        points = np.vstack([view.source[None, :], corners])
        lines = [2, 0, 1, 2, 0, 2, 2, 0, 3, 2, 0, 4, 5, 1, 2, 3, 4, 1]
        return pv.PolyData(points, lines=np.array(lines))

    @staticmethod
    def _new_image_data(w: int, h: int):
        image = pv.ImageData(dimensions=(w, h, 1))
        buffer = np.zeros((h, w), dtype=np.uint8)
        vtk_array = numpy_support.numpy_to_vtk(buffer.reshape(-1), deep=False)
        vtk_array.SetName("image")
        image.GetPointData().SetScalars(vtk_array)
        return image, buffer

    def view_actors(self, index: int) -> _ViewActors:
        return self._view_actors[index]

    # -- images -----------------------------------------------------------------------------
    def set_images(self, images, window_levels=None) -> None:
        """Update the plane textures in place (any dtype; percentile window unless given)."""
        for k, va in enumerate(self._view_actors):
            image = images[k] if k < len(images) else None
            if image is None:
                va.buffer[:] = 40
            else:
                image = np.asarray(image)
                window = window_levels[k] if window_levels is not None and k < len(window_levels) else None
                h, w = image.shape[:2]
                if va.buffer.shape != (h, w):  # rare: image size differs from the calibration
                    va.image_data, va.buffer = self._new_image_data(w, h)
                    va.texture.SetInputData(va.image_data)
                window_image(image, window, out=va.buffer)
            va.image_data.GetPointData().GetScalars().Modified()
            va.image_data.Modified()
        self.render()

    # -- models ----------------------------------------------------------------------------
    def set_model(self, component: str, vertices, faces, colour=None) -> None:
        """Add or replace a component's triangle mesh (smooth shading, keeps its pose)."""
        faces = np.asarray(faces, dtype=np.int64)
        cells = np.hstack([np.full((faces.shape[0], 1), 3, dtype=np.int64), faces]).ravel()
        mesh = pv.PolyData(np.asarray(vertices, dtype=np.float64), faces=cells)
        colour = colour or MODEL_COLOURS.get(component, FALLBACK_MODEL_COLOUR)
        old = self._models.pop(component, None)
        visible = True
        if old is not None:
            visible = bool(old.visibility)
            self.plotter.remove_actor(old, render=False)
        actor = self.plotter.add_mesh(
            mesh, color=colour, smooth_shading=True, split_sharp_edges=True, specular=0.5, specular_power=25,
            diffuse=0.8, ambient=0.15, name=f"model_{component}", render=False, reset_camera=False,
        )
        actor.visibility = visible
        self._models[component] = actor
        if component in self._poses:
            actor.user_matrix = pose_to_matrix(self._poses[component])
        if self._gizmo_component == component:
            self.enable_gizmo(component, self._gizmo_callback)
        self.render()

    def remove_model(self, component: str) -> None:
        """Take a component's model out of the scene (its file is gone, or another
        project is shown)."""
        actor = self._models.pop(component, None)
        if actor is not None:
            if self._gizmo_component == component:
                self.disable_gizmo()
            self.plotter.remove_actor(actor, render=False)
            self.render()

    def model_actor(self, component: str):
        return self._models[component]

    @property
    def components(self) -> list[str]:
        return list(self._models)

    def set_pose(self, component: str, pose) -> None:
        """Place a component: the actor's user matrix becomes pose_to_matrix(pose)."""
        pose = np.asarray(pose, dtype=float).reshape(6)
        self._poses[component] = pose
        actor = self._models.get(component)
        if actor is None:
            return
        matrix = pose_to_matrix(pose)
        actor.user_matrix = matrix
        if self._gizmo is not None and self._gizmo_component == component:
            self._sync_gizmo()
        self.render()

    def pose(self, component: str):
        return self._poses.get(component)

    def set_model_visible(self, component: str, visible: bool) -> None:
        actor = self._models.get(component)
        if actor is not None:
            actor.visibility = bool(visible)
            self.render()

    # -- contact points -----------------------------------------------------------------------
    def set_contact_points(self, points: dict | None) -> None:
        """The condyles' lowest points (world mm, ``{"medial": (3,), "lateral": (3,)}``) as
        balls drawn over the models (they lie between the femur and the tray, hidden
        otherwise); None, or no finite point, hides them."""
        finite = {name: np.asarray(p, dtype=float) for name, p in (points or {}).items()
                  if np.all(np.isfinite(p))}
        if not finite:
            if self._contact is not None:
                self._contact.visibility = False
                self.render()
            return
        cloud = pv.PolyData(np.array(list(finite.values())))
        cloud["colour"] = np.array([CONTACT_COLOURS[name] for name in finite])
        self._contact = self.plotter.add_mesh(  # the same name replaces the previous actor
            cloud, scalars="colour", rgb=True, point_size=14, render_points_as_spheres=True, name="contact_points",
            render=False, reset_camera=False, pickable=False)
        mapper = self._contact.mapper  # a depth offset toward the camera: never hidden by a model
        mapper.SetResolveCoincidentTopologyToPolygonOffset()
        mapper.SetRelativeCoincidentTopologyPointOffsetParameter(-1e6)
        self.render()

    @property
    def contact_actor(self):
        """The contact points' actor (None before any was shown)."""
        return self._contact

    # -- rays ---------------------------------------------------------------------------------
    def set_rays(self, view_index: int, points_px, max_rays: int = 60) -> None:
        """Rays from the source through outline pixels to the plane (None clears)."""
        va = self._view_actors[view_index]
        mesh = va.rays_mesh
        if points_px is None or len(points_px) == 0:
            mesh.lines = np.zeros(0, dtype=np.int64)
            mesh.points = va.view.source[None, :]
        else:
            pts = np.asarray(points_px, dtype=float).reshape(-1, 2)
            if len(pts) > max_rays:
                pts = pts[np.linspace(0, len(pts) - 1, max_rays).round().astype(int)]
            ends = va.view.pixel_to_plane(pts)  # va.view is the drawn (display) view
            n = len(ends)
            mesh.points = np.vstack([va.view.source[None, :], ends])
            lines = np.column_stack([np.full(n, 2), np.zeros(n, dtype=int), np.arange(1, n + 1)])
            mesh.lines = lines.ravel()
        mesh.Modified()
        self.render()

    def set_rays_visible(self, visible: bool) -> None:
        self._rays_visible = bool(visible)
        for va in self._view_actors:
            va.rays.visibility = self._rays_visible
        self.render()

    @property
    def rays_visible(self) -> bool:
        return self._rays_visible

    # -- camera ---------------------------------------------------------------------------
    def _world_up(self) -> np.ndarray:
        """"Up" of the set-up: image up (-e_v) of the views, made normal to both beams."""
        if not self.views:
            return np.array([0.0, 0.0, 1.0])
        up = -np.mean([v.e_v for v in self.views], axis=0)
        if len(self.views) >= 2:
            cross = np.cross(self.views[0].normal, self.views[1].normal)
            if np.linalg.norm(cross) > 1e-3:
                cross /= np.linalg.norm(cross)
                up = cross if cross @ up >= 0 else -cross
        return up / np.linalg.norm(up)

    def _target(self) -> np.ndarray:
        """Where the beams cross (the subject), else the plane centre."""
        if len(self.views) >= 2:
            try:
                point, _ = closest_point_between_rays(self.views[0].source, self.views[0].normal,
                                                      self.views[1].source, self.views[1].normal)
                return point
            except ValueError:
                pass
        if self.views:
            return self.views[0].source + 0.7 * self.views[0].distance * self.views[0].normal
        return np.zeros(3)

    def camera_preset(self, name: str) -> None:
        """"view1", "view2" (from that source, image as the X-ray), "top" or "iso"."""
        cam = self.plotter.camera
        name = name.lower().replace(" ", "")
        if name.startswith("view"):
            index = int(name[4:]) - 1
            if not 0 <= index < len(self.views):
                raise ValueError(f"there is no view {index + 1}")
            view = self.display_views[index]
            w, h = view.image_size
            centre = view.pixel_to_plane(np.array([[(w - 1) / 2, (h - 1) / 2]]))[0]
            cam.position = tuple(view.source)
            cam.focal_point = tuple(centre)
            cam.up = tuple(-view.e_v)
            ww, wh = self.plotter.window_size
            aspect = ww / max(wh, 1)
            dist = float(np.linalg.norm(centre - view.source))
            half = max(h * view.pitch[1] / 2, w * view.pitch[0] / 2 / aspect) * 1.04
            cam.view_angle = float(np.degrees(2 * np.arctan(half / dist)))
            self.plotter.renderer.reset_camera_clipping_range()
        elif name in ("top", "iso", "implant"):
            up = self._world_up()
            target = self._target()
            if name == "top":
                direction = up  # camera above, looking down
                beams = np.mean([v.normal for v in self.views], axis=0) if self.views else np.array([0, 1.0, 0])
                cam_up = beams - (beams @ up) * up
                if np.linalg.norm(cam_up) < 1e-6:
                    cam_up = np.array([0.0, 1.0, 0.0]) if abs(up[1]) < 0.9 else np.array([1.0, 0, 0])
            else:
                beams = -np.mean([v.normal for v in self.views], axis=0) if self.views else np.array([1.0, 1, 0])
                horiz = beams - (beams @ up) * up
                horiz /= max(np.linalg.norm(horiz), 1e-9)
                side = np.cross(up, horiz)
                direction = 0.75 * horiz + 0.45 * side + 0.5 * up
                cam_up = up
            direction = direction / np.linalg.norm(direction)
            cam.view_angle = 30.0
            cam.focal_point = tuple(target)
            cam.position = tuple(target + 1000.0 * direction)
            cam.up = tuple(cam_up)
            bounds = self._model_bounds() if name == "implant" else None
            if bounds is not None:  # the implants fill the view, seen from the iso direction
                centre = np.array([(bounds[0] + bounds[1]) / 2, (bounds[2] + bounds[3]) / 2,
                                   (bounds[4] + bounds[5]) / 2])
                cam.focal_point = tuple(centre)
                cam.position = tuple(centre + 1000.0 * direction)
                self.plotter.reset_camera(render=False, bounds=bounds)
                cam.Zoom(0.8)  # some room around the implants
            else:
                self.plotter.reset_camera(render=False)
                cam.Zoom(1.25)  # the bounding sphere is loose around the long beams
        else:
            raise ValueError(f"unknown camera preset {name!r} (use {', '.join(CAMERA_PRESETS)})")
        self.render()

    def _model_bounds(self):
        """Bounds (xmin, xmax, ymin, ymax, zmin, zmax) of the visible posed models, or None."""
        boxes = [np.asarray(a.GetBounds()) for a in self._models.values() if a.GetVisibility()]
        if not boxes:
            return None
        b = np.array(boxes)
        return (b[:, 0].min(), b[:, 1].max(), b[:, 2].min(), b[:, 3].max(), b[:, 4].min(), b[:, 5].max())

    def reset_camera(self) -> None:
        self.camera_preset("iso") if self.views else self.plotter.reset_camera(render=False)
        self.render()

    # -- gizmo ------------------------------------------------------------------------------
    def enable_gizmo(self, component: str, callback) -> bool:
        """Drag handles on a model; ``callback(component, pose)`` on every move. False when the
        plotter has no interactor (the gizmo needs mouse events)."""
        self.disable_gizmo()
        actor = self._models.get(component)
        if actor is None or getattr(self.plotter, "iren", None) is None:
            return False
        self._gizmo_component, self._gizmo_callback = component, callback
        if actor.user_matrix is None:
            actor.user_matrix = np.eye(4)
        self._gizmo = self.plotter.add_affine_transform_widget(
            actor, origin=tuple(actor.center), scale=0.45, release_callback=self._gizmo_released,
        )
        # runs after the widget's own move observer (lower priority), sees the new matrix
        interactor = self.plotter.iren.interactor
        self._gizmo_observer = interactor.AddObserver("MouseMoveEvent", self._gizmo_moved, -1.0)
        return True

    def disable_gizmo(self) -> None:
        if self._gizmo is not None:
            self._gizmo.remove()
        if self._gizmo_observer is not None and getattr(self.plotter, "iren", None) is not None:
            self.plotter.iren.interactor.RemoveObserver(self._gizmo_observer)
        self._gizmo = self._gizmo_observer = None
        self._gizmo_component = self._gizmo_callback = None

    @property
    def gizmo(self):
        return self._gizmo

    def _gizmo_moved(self, *_args) -> None:
        gizmo = self._gizmo
        if gizmo is None or not gizmo._pressing_down:
            return
        self._emit_gizmo_pose()

    def _gizmo_released(self, _matrix) -> None:
        self._emit_gizmo_pose()
        self._sync_gizmo()  # the handles follow the model

    def _emit_gizmo_pose(self) -> None:
        component = self._gizmo_component
        actor = self._models.get(component)
        if actor is None:
            return
        pose = matrix_to_pose(actor.user_matrix)
        self._poses[component] = pose
        if self._gizmo_callback is not None:
            self._gizmo_callback(component, pose)

    def _sync_gizmo(self) -> None:
        # the widget composes drags with its cached matrix: keep it equal to the actor's
        actor = self._models[self._gizmo_component]
        self._gizmo._cached_matrix = actor.user_matrix
        self._gizmo.origin = tuple(actor.center)

    # -- rendering ------------------------------------------------------------------------
    def render(self) -> None:
        """Request a render (coalesced by the widget when it installed ``render_callback``)."""
        if self.render_callback is not None:
            self.render_callback()
        else:
            self.plotter.render()

    def close(self) -> None:
        self.disable_gizmo()
        self.render_callback = None
