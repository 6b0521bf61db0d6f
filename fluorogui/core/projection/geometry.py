"""Virtual fluoroscope: one source–intensifier pair ("view") and the projection of Eq. (3).

A view holds the source position, the intensifier plane (unit normal ``n`` from the
source towards the plane, in-plane unit axes ``e_u`` / ``e_v`` along image columns and
rows), the source–intensifier distance ``l``, the pixel pitch (mm, per axis), the
principal point (pixels) and the image size. Pixel ``(u, v)`` = (column, row) with the
origin at the centre of the top-left pixel and ``v`` pointing down.
"""
from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

#: Pixel pitch recorded when a calibration format carries none (the paper's 315 mm / 1024 px).
DEFAULT_PITCH_MM = 315.0 / 1024.0


class GeometryError(ValueError):
    """A calibration that does not describe a valid projection."""


def _unit(v) -> np.ndarray:
    v = np.asarray(v, dtype=float)
    return v / np.linalg.norm(v)


@dataclass(frozen=True)
class View:
    """One source–intensifier pair. All lengths in mm, all pixel quantities in pixels."""

    source: np.ndarray
    normal: np.ndarray
    e_u: np.ndarray
    e_v: np.ndarray
    distance: float
    pitch: tuple[float, float]
    principal_point: tuple[float, float]
    image_size: tuple[int, int]  # (width, height)
    name: str = ""
    extra: dict = field(default_factory=dict, compare=False)

    def __post_init__(self):
        for key in ("source", "normal", "e_u", "e_v"):
            value = np.asarray(getattr(self, key), dtype=float).reshape(3)
            object.__setattr__(self, key, value)
        object.__setattr__(self, "pitch", tuple(float(p) for p in self.pitch))
        object.__setattr__(self, "principal_point", tuple(float(p) for p in self.principal_point))
        object.__setattr__(self, "image_size", tuple(int(s) for s in self.image_size))
        object.__setattr__(self, "distance", float(self.distance))
        self.validate()

    # -- checks -----------------------------------------------------------------------
    def validate(self) -> None:
        numbers = np.concatenate(
            [self.source, self.normal, self.e_u, self.e_v, [self.distance], self.pitch, self.principal_point]
        )
        if not np.all(np.isfinite(numbers)):
            raise GeometryError("calibration contains NaN or infinite values")
        if self.distance <= 0 or min(self.pitch) <= 0:
            raise GeometryError("source-intensifier distance and pixel pitch must be positive")
        if min(self.image_size) <= 0:
            raise GeometryError("image size must be positive")
        for key in ("normal", "e_u", "e_v"):
            if abs(np.linalg.norm(getattr(self, key)) - 1.0) > 1e-6:
                raise GeometryError(f"{key} is not a unit vector")
        if abs(self.e_u @ self.e_v) > 1e-6 or abs(self.e_u @ self.normal) > 1e-6 or abs(self.e_v @ self.normal) > 1e-6:
            raise GeometryError("intensifier axes and normal are not orthogonal")

    # -- derived quantities -------------------------------------------------------------
    @property
    def focal_px(self) -> tuple[float, float]:
        """Source-intensifier distance in pixels along u and v (pinhole fx, fy)."""
        return self.distance / self.pitch[0], self.distance / self.pitch[1]

    @property
    def center(self) -> np.ndarray:
        """3D point of the image centre on the intensifier plane."""
        w, h = self.image_size
        return self.pixel_to_plane(np.array([[(w - 1) / 2.0, (h - 1) / 2.0]]))[0]

    @property
    def K(self) -> np.ndarray:
        fx, fy = self.focal_px
        cx, cy = self.principal_point
        return np.array([[fx, 0, cx], [0, fy, cy], [0, 0, 1.0]])

    @property
    def R(self) -> np.ndarray:
        """World-to-camera rotation (rows e_u, e_v, n)."""
        return np.vstack([self.e_u, self.e_v, self.normal])

    @property
    def t(self) -> np.ndarray:
        return -self.R @ self.source

    # -- projection ------------------------------------------------------------------------
    def project(self, points: np.ndarray) -> np.ndarray:
        """World points (N, 3) to pixels (N, 2) through Eq. (3)."""
        return self.project_with_depth(points)[0]

    def project_with_depth(self, points: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Pixels (N, 2) as ``project`` and each point's depth along the normal (N,)."""
        d = np.asarray(points, dtype=float) - self.source
        w = d @ self.normal
        fx, fy = self.focal_px
        cx, cy = self.principal_point
        out = np.empty((d.shape[0], 2))
        out[:, 0] = cx + fx * (d @ self.e_u) / w
        out[:, 1] = cy + fy * (d @ self.e_v) / w
        return out, w

    def project_plane(self, points: np.ndarray) -> np.ndarray:
        """World points to 3D points on the intensifier plane (Eq. 3 literally)."""
        d = np.asarray(points, dtype=float) - self.source
        return self.source + d * (self.distance / (d @ self.normal))[:, None]

    def project_jacobian(self, points: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Pixels (N, 2) and their derivatives with respect to the world point, (N, 2, 3)."""
        d = np.asarray(points, dtype=float) - self.source
        w = d @ self.normal
        du, dv = d @ self.e_u, d @ self.e_v
        fx, fy = self.focal_px
        cx, cy = self.principal_point
        uv = np.column_stack([cx + fx * du / w, cy + fy * dv / w])
        J = np.empty((d.shape[0], 2, 3))
        J[:, 0, :] = fx * (self.e_u[None, :] - (du / w)[:, None] * self.normal[None, :]) / w[:, None]
        J[:, 1, :] = fy * (self.e_v[None, :] - (dv / w)[:, None] * self.normal[None, :]) / w[:, None]
        return uv, J

    def pixel_to_plane(self, uv: np.ndarray) -> np.ndarray:
        """Pixels (N, 2) to 3D points on the intensifier plane."""
        uv = np.atleast_2d(np.asarray(uv, dtype=float))
        cx, cy = self.principal_point
        base = self.source + self.distance * self.normal
        return (
            base
            + ((uv[:, 0] - cx) * self.pitch[0])[:, None] * self.e_u
            + ((uv[:, 1] - cy) * self.pitch[1])[:, None] * self.e_v
        )

    def pixel_to_mm(self, uv: np.ndarray) -> np.ndarray:
        """Pixels to 2D intensifier-plane millimetres about the principal point."""
        uv = np.atleast_2d(np.asarray(uv, dtype=float))
        cx, cy = self.principal_point
        return np.column_stack([(uv[:, 0] - cx) * self.pitch[0], (uv[:, 1] - cy) * self.pitch[1]])

    def mm_to_pixel(self, xy: np.ndarray) -> np.ndarray:
        xy = np.atleast_2d(np.asarray(xy, dtype=float))
        cx, cy = self.principal_point
        return np.column_stack([xy[:, 0] / self.pitch[0] + cx, xy[:, 1] / self.pitch[1] + cy])

    def ray(self, uv) -> tuple[np.ndarray, np.ndarray]:
        """Back-projected ray(s) through pixel(s): origin (the source) and unit directions."""
        p = self.pixel_to_plane(uv)
        d = p - self.source
        return self.source.copy(), d / np.linalg.norm(d, axis=1, keepdims=True)

    def mm_per_px(self) -> float:
        """Mean pixel pitch on the intensifier (the unit of the paper's objective)."""
        return float(np.mean(self.pitch))

    # -- construction ------------------------------------------------------------------
    @classmethod
    def from_pinhole(cls, K, R, t, image_size, *, pitch: float | None = None, name: str = "") -> "View":
        """A view from OpenCV extrinsics ``x_cam = R X + t`` and intrinsics ``K`` (pixels)."""
        K = np.asarray(K, dtype=float)
        R = np.asarray(R, dtype=float)
        t = np.asarray(t, dtype=float).reshape(3)
        if K.shape != (3, 3) or R.shape != (3, 3):
            raise GeometryError("camera matrix and rotation must be 3x3")
        if not (np.all(np.isfinite(K)) and np.all(np.isfinite(R)) and np.all(np.isfinite(t))):
            raise GeometryError("calibration contains NaN or infinite values")
        if abs(np.linalg.det(K)) < 1e-9 or K[0, 0] <= 0 or K[1, 1] <= 0:
            raise GeometryError("camera matrix is singular or has non-positive focal lengths")
        if abs(K[0, 1]) > 1e-6 * K[0, 0]:
            raise GeometryError("camera matrix has a skew term, which is not supported")
        if not np.allclose(R @ R.T, np.eye(3), atol=1e-5) or np.linalg.det(R) < 0:
            raise GeometryError("rotation matrix is not a proper rotation")
        # re-orthonormalise the rotation read at ~1e-9 precision
        U, _, Vt = np.linalg.svd(R)
        R = U @ Vt
        pu = float(pitch) if pitch else DEFAULT_PITCH_MM
        fx, fy = K[0, 0] / K[2, 2], K[1, 1] / K[2, 2]
        distance = fx * pu
        pv = distance / fy
        return cls(
            source=-R.T @ t,
            normal=R[2],
            e_u=R[0],
            e_v=R[1],
            distance=distance,
            pitch=(pu, pv),
            principal_point=(K[0, 2] / K[2, 2], K[1, 2] / K[2, 2]),
            image_size=image_size,
            name=name,
        )

    @classmethod
    def looking_at(cls, source, target, up, distance, *, image_size, pitch, name: str = "") -> "View":
        """A view whose principal ray goes from ``source`` through ``target``, principal point
        at the image centre; ``up`` sets the direction of decreasing rows (v)."""
        source = np.asarray(source, dtype=float)
        n = _unit(np.asarray(target, dtype=float) - source)
        e_v = -_unit(np.asarray(up, dtype=float) - (np.asarray(up, dtype=float) @ n) * n)
        e_u = np.cross(e_v, n)
        w, h = image_size
        return cls(source, n, e_u, e_v, distance, (pitch, pitch), ((w - 1) / 2.0, (h - 1) / 2.0), image_size, name)

    # -- serialisation -------------------------------------------------------------------
    def to_dict(self) -> dict:
        return {
            "name": self.name,
            "source_mm": self.source.tolist(),
            "normal": self.normal.tolist(),
            "e_u": self.e_u.tolist(),
            "e_v": self.e_v.tolist(),
            "distance_mm": self.distance,
            "pitch_mm": list(self.pitch),
            "principal_point_px": list(self.principal_point),
            "image_size_px": list(self.image_size),
        } | ({"distortion": self.extra["distortion"]} if self.extra.get("distortion") else {})

    @classmethod
    def from_dict(cls, d: dict) -> "View":
        try:
            view = cls(
                source=d["source_mm"],
                normal=d["normal"],
                e_u=d["e_u"],
                e_v=d["e_v"],
                distance=d["distance_mm"],
                pitch=d["pitch_mm"],
                principal_point=d["principal_point_px"],
                image_size=d["image_size_px"],
                name=d.get("name", ""),
            )
            if d.get("distortion"):
                if not isinstance(d["distortion"], dict) or "model" not in d["distortion"]:
                    raise GeometryError("view's 'distortion' must be an object with a 'model'")
                view.extra["distortion"] = d["distortion"]  # a correction (fluorogui.core.calibration.distortion)
            return view
        except KeyError as exc:
            raise GeometryError(f"view is missing the field {exc.args[0]!r}") from None
        except (TypeError, ValueError) as exc:
            if isinstance(exc, GeometryError):
                raise
            raise GeometryError(f"view has a malformed field: {exc}") from None


def closest_point_between_rays(o1, d1, o2, d2) -> tuple[np.ndarray, float]:
    """Midpoint of the shortest segment between two rays and its length (the miss distance)."""
    o1, d1, o2, d2 = (np.asarray(a, dtype=float).reshape(3) for a in (o1, d1, o2, d2))
    d1, d2 = _unit(d1), _unit(d2)
    w0 = o1 - o2
    b = d1 @ d2
    denom = 1.0 - b * b
    if denom < 1e-12:
        raise GeometryError("the two rays are parallel")
    s = (b * (d2 @ w0) - (d1 @ w0)) / denom
    u = ((d2 @ w0) - b * (d1 @ w0)) / denom
    p1, p2 = o1 + s * d1, o2 + u * d2
    return (p1 + p2) / 2.0, float(np.linalg.norm(p1 - p2))


def triangulate(views, pixels) -> tuple[np.ndarray, float]:
    """3D point seen at ``pixels[k]`` in ``views[k]`` (two views) and the rays' miss distance."""
    (o1, d1), (o2, d2) = (v.ray(p) for v, p in zip(views, pixels))
    return closest_point_between_rays(o1, d1[0], o2, d2[0])
