"""Bone and cement about an implant in the X-ray image model (``fluorogui.reference.zone``):
its ray integrals against quadrature, the bone's side of the plate, the plate's underside
of a tray mesh, and the sloped background it puts next to the metal."""
import numpy as np
import pytest

from fluorogui.core.projection.geometry import View
from fluorogui.reference.xray import MU_METAL, Body, XrayModel, xray_image
from fluorogui.reference.zone import Zone, plate_underside, tray_zone

# looking along +x from x = -1000; the detector 1200 mm from the source, 0.5 mm pixels
VIEW = View.looking_at([-1000.0, 0, 0], [0, 0, 0], [0, 0, 1], 1200.0, image_size=(128, 128), pitch=0.5)


def _sphere(radius=10.0):
    import pyvista as pv

    tri = pv.Sphere(radius=radius, theta_resolution=120, phi_resolution=120).triangulate()
    return np.asarray(tri.points, dtype=float), np.asarray(tri.faces).reshape(-1, 4)[:, 1:]


def _expected(u, v, radius, mu, thickness, softness, plane_z=None):
    """The zone's integral along the ray through pixel (u, v), by quadrature: the density
    at the distance | |x| - R | from a sphere of radius R at the origin."""
    cx, cy = VIEW.principal_point
    d = 1200.0 * VIEW.normal + (u - cx) * 0.5 * VIEW.e_u + (v - cy) * 0.5 * VIEW.e_v
    d /= np.linalg.norm(d)
    s = np.arange(900.0, 1100.0, 0.005)  # mm from the source
    x = VIEW.source[None, :] + s[:, None] * d[None, :]
    rho = mu / (1.0 + np.exp((np.abs(np.linalg.norm(x, axis=1) - radius) - thickness) / softness))
    if plane_z is not None:
        rho = rho / (1.0 + np.exp(-(x[:, 2] - plane_z) / softness))
    return float(rho.sum() * 0.005)


def test_zone_integral_is_the_density_along_the_ray():
    v, f = _sphere()
    zone = Zone(v, f, mu=0.05, thickness=3.0, softness=0.5, voxel=0.25)
    cx, cy = VIEW.principal_point
    # through the sphere, grazing it, and beyond it where only the zone's tail is
    # (pixels of 0.5 mm are 0.42 mm at the sphere: offsets 0, 9.6, 11.3, 13.3 mm)
    us = cx + np.array([0.0, 23.0, 27.0, 32.0])
    got = zone.integral(VIEW, us, np.full(4, cy))
    want = np.array([_expected(u, cy, 10.0, 0.05, 3.0, 0.5) for u in us])
    # measured: within 0.9 % through and beside the sphere, 2.2 % in the far tail (the
    # distance is read on a voxel grid)
    np.testing.assert_allclose(got, want, rtol=0.04)
    assert zone.integral(VIEW, np.array([cx + 60.0]), np.array([cy]))[0] == 0.0  # far off: nothing


def test_zone_lies_on_the_bone_side_of_its_plane():
    v, f = _sphere()
    zone = Zone(v, f, 0.05, 3.0, 0.5, plane=((0.0, 0.0, 0.0), (0.0, 0.0, 1.0)), voxel=0.25)
    cx, cy = VIEW.principal_point
    # rays passing 11.3 mm above and below the centre (v grows downward: above is -27 px)
    above, below = zone.integral(VIEW, np.full(2, cx), cy + np.array([-27.0, 27.0]))
    assert above == pytest.approx(_expected(cx, cy - 27.0, 10.0, 0.05, 3.0, 0.5, plane_z=0.0), rel=0.03)
    assert above > 0.1 and below < 1e-3 * above


def test_plate_underside_of_the_phantom_tray():
    from fluorogui.simulation.phantoms import tibial_component_mesh

    v, f = tibial_component_mesh()
    # its plate is 5 mm thick: top at z = 0, underside at z = -5 (the rim rounds off above it)
    assert plate_underside(np.asarray(v), np.asarray(f)) == pytest.approx(-5.0, abs=0.05)
    import pyvista as pv

    slab = pv.Box(bounds=(-20, 20, -15, 15, 0, 3)).triangulate()  # its only underside is its lowest 5 mm
    with pytest.raises(ValueError, match="looking down"):
        plate_underside(np.asarray(slab.points), np.asarray(slab.faces).reshape(-1, 4)[:, 1:])


def test_the_metal_stands_on_a_background_that_rises_on_the_bone_side_only():
    from fluorogui.simulation.phantoms import tibial_component_mesh

    v, f = (np.asarray(a) for a in tibial_component_mesh())
    M = np.eye(4)  # plate horizontal, keel down, seen edge-on
    model = XrayModel(supersample=2, photons=None, background=[])
    images = {name: xray_image(VIEW, [Body(v, f, MU_METAL)], XrayModel(**{**model.__dict__, "zones": zones}))
              for name, zones in (("plain", []), ("zone", [tray_zone(v, f, M)]))}
    # a column through the plate clear of the keel and its fin (y = -15 mm), rows at heights z
    def level(image, z_mm):
        u, v = VIEW.project(np.array([[0.0, -15.0, z_mm]]))[0]
        return image[int(round(v)), int(round(u))]

    plain, zone = images["plain"], images["zone"]
    # above the plate (the joint side: the plate's top is at z = 0) the zone changes nothing;
    # under it (underside at z = -5) it darkens the image, less and less further down
    assert [level(zone, z) for z in (1.5, 3.0, 6.0)] == pytest.approx([level(plain, z) for z in (1.5, 3.0, 6.0)],
                                                                     abs=1e-4)
    under = [level(plain, z) - level(zone, z) for z in (-6.0, -7.5, -9.0, -12.0)]
    assert under[0] > 0.03 and under[0] > under[1] > under[2] > under[3] >= -1e-6, under
