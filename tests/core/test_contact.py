"""Condylar contact on geometry whose answers are known by hand: sphere condyles (the lowest
point of a sphere is its centre minus its radius along the tibial axis, in any pose), a plane
and a dish insert (gaps in closed form), a femur turning about a known vertical axis (the
pivot), lift-off, rollback, and the left knee as the mirror image of the right."""
from __future__ import annotations

import numpy as np
import pytest
import pyvista as pv
from scipy.spatial.transform import Rotation

from fluorogui.core.knee.contact import (
    classify_liftoff,
    condyle_contact,
    pivot,
    place_insert,
    prepare_femur,
    rollback,
)
from fluorogui.core.projection.pose import pose_to_matrix

RADII = {"medial": 20.0, "lateral": 22.0}  # unequal, so that a swapped condyle shows
CENTRES = {"medial": np.array([-22.0, 1.0, 0.0]), "lateral": np.array([23.0, -1.0, 1.0])}  # right knee: medial is -x


def sphere(centre, radius, resolution=(120, 60)):
    s = pv.Sphere(radius=radius, center=centre, theta_resolution=resolution[0], phi_resolution=resolution[1])
    return np.asarray(s.points, float), np.asarray(s.faces).reshape(-1, 4)[:, 1:].astype(np.int64)


def condyles(resolution=(120, 60), mirror=False):
    """Two sphere condyles as one femoral mesh (model = anatomical frame); ``mirror``: the
    left knee's component, the right one reflected in its sagittal plane."""
    parts = [sphere(CENTRES[n] * ([-1, 1, 1] if mirror else 1), RADII[n], resolution) for n in ("medial", "lateral")]
    vertices = np.vstack([parts[0][0], parts[1][0]])
    faces = np.vstack([parts[0][1], parts[1][1] + len(parts[0][0])])
    return vertices, faces[:, ::-1] if mirror else faces


def rotation_z(deg):
    out = np.eye(4)
    c, s = np.cos(np.radians(deg)), np.sin(np.radians(deg))
    out[:2, :2] = [[c, -s], [s, c]]
    return out


def poses(count=24, seed=3):
    """Femoral poses (model -> world, the tibia at the identity) with flexion 0-120 deg,
    rotation +/-15 deg, some varus and translation."""
    rng = np.random.default_rng(seed)
    out = []
    for k in range(count):
        flexion = 120.0 * k / (count - 1)
        femur = pose_to_matrix([rng.uniform(-3, 3), rng.uniform(-4, 4), 26 + rng.uniform(-2, 2),
                                flexion, rng.uniform(-3, 3), 0])
        out.append(rotation_z(rng.uniform(-15, 15)) @ femur)
    return out


def analytic_lowest(femur_pose, name):
    return (femur_pose @ [*CENTRES[name], 1])[:3] - [0, 0, RADII[name]]


def test_lowest_points_of_sphere_condyles_are_their_centres_minus_the_radius():
    femur = prepare_femur(*condyles(), np.eye(4))
    errors = []
    for pose in poses():
        contact = condyle_contact(femur, pose, np.eye(4), tibial_frame=np.eye(4), side="right")
        for name in ("medial", "lateral"):
            got, want = getattr(contact, name).lowest, analytic_lowest(pose, name)
            errors.append([np.linalg.norm(got[:2] - want[:2]), abs(got[2] - want[2])])
    errors = np.array(errors)
    # measured (1.17 mm mesh spacing): 1.8e-5 mm in position, 2.7e-6 mm in height; the issue asks 0.05 and 0.01
    assert errors[:, 0].max() < 4e-5
    assert errors[:, 1].max() < 6e-6


def test_the_fitted_point_is_not_the_nearest_vertex():
    """On a coarse sphere (4.1 mm spacing) the lowest vertex is up to 1.8 mm off; the fitted
    surface is not."""
    vertices, faces = condyles(resolution=(36, 18))
    femur = prepare_femur(vertices, faces, np.eye(4))
    fitted, vertex_only = [], []
    for pose in poses():
        contact = condyle_contact(femur, pose, np.eye(4), tibial_frame=np.eye(4), side="right")
        want = analytic_lowest(pose, "medial")
        placed = vertices[:len(vertices) // 2] @ pose[:3, :3].T + pose[:3, 3]
        vertex = placed[np.argmin(placed[:, 2])]
        vertex_only.append([np.linalg.norm(vertex[:2] - want[:2]), abs(vertex[2] - want[2])])
        fitted.append([np.linalg.norm(contact.medial.lowest[:2] - want[:2]), abs(contact.medial.lowest[2] - want[2])])
    assert np.max(vertex_only, axis=0)[0] > 1.0  # measured 1.83 mm (0.084 mm in height)
    # measured: 0.0054 mm in position, 0.0056 mm in height
    assert np.max(fitted, axis=0)[0] < 0.011 and np.max(fitted, axis=0)[1] < 0.011


def test_gaps_to_a_plane_insert_and_a_tilted_insert_frame():
    femur = prepare_femur(*condyles(), np.eye(4))
    square = np.array([[-60, -60, 0], [60, -60, 0], [60, 60, 0], [-60, 60, 0.0]])
    plane = place_insert(square, np.array([[0, 1, 2], [0, 2, 3]]), np.eye(4))
    lifted = np.eye(4)
    lifted[2, 3] = 3.0  # the insert 3 mm above the tray, by its insert -> tray matrix
    raised = place_insert(square, np.array([[0, 1, 2], [0, 2, 3]]), np.eye(4), lifted)
    errors = []
    for pose in poses():
        contact = condyle_contact(femur, pose, np.eye(4), tibial_frame=np.eye(4), side="right", insert=plane)
        higher = condyle_contact(femur, pose, np.eye(4), tibial_frame=np.eye(4), side="right", insert=raised)
        for name in ("medial", "lateral"):
            height = analytic_lowest(pose, name)[2]
            errors += [abs(getattr(contact, name).gap_mm - height), abs(getattr(higher, name).gap_mm - (height - 3))]
            np.testing.assert_allclose(getattr(contact, name).insert_point[:2], analytic_lowest(pose, name)[:2],
                                       atol=0.01)
    assert max(errors) < 7e-6  # measured 3.4e-6 mm; the issue asks 0.01


def test_gap_to_a_dish_insert():
    """A sphere of radius r in a concave spherical dish of radius R centred at D: the gap
    is R - r - |c - D|."""
    dish_radius, dish_centre = 60.0, np.array([0.0, 0.0, 58.0])
    ball = pv.Sphere(radius=dish_radius, center=dish_centre, theta_resolution=240, phi_resolution=240)
    points, faces = np.asarray(ball.points, float), np.asarray(ball.faces).reshape(-1, 4)[:, 1:]
    bottom = faces[np.all(points[faces, 2] < 15, axis=1)]  # the dish: the sphere's bottom, from z = -2 to 15
    insert = place_insert(points, bottom, np.eye(4))
    femur = prepare_femur(*condyles(), np.eye(4))
    errors = []
    for pose in poses(8, seed=5):
        pose = pose.copy()
        pose[2, 3] += 4.0
        contact = condyle_contact(femur, pose, np.eye(4), tibial_frame=np.eye(4), side="right", insert=insert)
        for name in ("medial", "lateral"):
            centre = (pose @ [*CENTRES[name], 1])[:3]
            want = dish_radius - RADII[name] - np.linalg.norm(centre - dish_centre)
            errors.append(abs(getattr(contact, name).gap_mm - want))
    assert max(errors) < 0.01  # measured 0.0035 mm (the dish's own facets: 0.8 mm edges on a 60 mm radius)


def test_penetration_gives_a_negative_gap_and_liftoff_by_gap():
    femur = prepare_femur(*condyles(), np.eye(4))
    square = np.array([[-60, -60, 0], [60, -60, 0], [60, 60, 0], [-60, 60, 0.0]])
    plane = place_insert(square, np.array([[0, 1, 2], [0, 2, 3]]), np.eye(4))
    pose = pose_to_matrix([0, 0, 19.5, 0, 0, 0])  # medial sphere 0.5 mm into the plane, lateral 2.5 mm above
    contact = condyle_contact(femur, pose, np.eye(4), tibial_frame=np.eye(4), side="right", insert=plane)
    assert contact.medial.gap_mm == pytest.approx(-0.5, abs=0.002)
    assert contact.lateral.gap_mm == pytest.approx(-1.5, abs=0.002)  # radius 22, centre 1 mm higher
    tilted = pose_to_matrix([0, 0, 21.6, 0, -4, 0])  # tilted: the lateral condyle 2.2 mm up, the medial 0.06
    contact = condyle_contact(femur, tilted, np.eye(4), tibial_frame=np.eye(4), side="right", insert=plane)
    assert contact.lateral.gap_mm > 1.0 > contact.medial.gap_mm
    assert contact.liftoff == "lateral"


def test_liftoff_without_an_insert_is_the_difference_of_heights():
    from fluorogui.core.knee.contact import CondyleContact

    low, high = CondyleContact(np.array([0, 0, 1.0])), CondyleContact(np.array([0, 0, 2.5]))
    assert classify_liftoff(low, high) == "lateral"
    assert classify_liftoff(high, low) == "medial"
    assert classify_liftoff(low, CondyleContact(np.array([0, 0, 1.9]))) == "none"
    assert classify_liftoff(low, CondyleContact(np.array([0, 0, 1.9])), liftoff_mm=0.5) == "lateral"


def test_pivot_of_a_motion_about_a_known_vertical_axis():
    """The femur flexes and turns +/-15 deg about a vertical axis through a point of its
    medial-lateral line 40 % of the way from the medial condyle: that point is the pivot."""
    femur = prepare_femur(*condyles(), np.eye(4))
    axis = CENTRES["medial"] + 0.4 * (CENTRES["lateral"] - CENTRES["medial"])
    medial, lateral = [], []
    for k, flexion in enumerate(np.linspace(0, 120, 25)):
        turn = 15 * np.sin(k / 3.0)
        about = np.eye(4)
        about[:2, 3] = axis[:2]
        back = np.eye(4)
        back[:2, 3] = -axis[:2]
        pose = about @ rotation_z(turn) @ back @ pose_to_matrix([0, 0, 25, 0, 0, 0])
        # flexion about the line through both sphere centres keeps the lowest points below them
        line = CENTRES["lateral"] - CENTRES["medial"]
        rotvec = np.radians(flexion) * line / np.linalg.norm(line)
        flex = np.eye(4)
        flex[:3, :3] = Rotation.from_rotvec(rotvec).as_matrix()
        flex[:3, 3] = CENTRES["medial"] - flex[:3, :3] @ CENTRES["medial"]
        contact = condyle_contact(femur, pose @ flex, np.eye(4), tibial_frame=np.eye(4), side="right")
        medial.append(contact.medial.lowest[:2])
        lateral.append(contact.lateral.lowest[:2])
    found = pivot(medial, lateral)
    want = axis[:2]
    assert found.frames_used == 25 and found.frames_ignored == 0
    assert np.hypot(found.x_mm - want[0], found.y_mm - want[1]) < 8e-6  # measured 3.8e-6 mm; the issue asks 0.5
    assert found.kind == "central"  # 40 % of the way: the middle third


def test_pivot_kinds_and_frames_that_do_not_constrain_it():
    angles = np.radians(np.linspace(-15, 15, 11))
    for where, kind in ((-20.0, "medial"), (0.0, "central"), (18.0, "lateral")):
        medial = np.column_stack([where + (-22 - where) * np.cos(angles), (-22 - where) * np.sin(angles)])
        lateral = np.column_stack([where + (22 - where) * np.cos(angles), (22 - where) * np.sin(angles)])
        medial[3] = np.nan  # a frame without values
        lateral[5] = medial[5] + [4.0, 0]  # condyles 4 mm apart: no line
        found = pivot(medial, lateral)
        assert found.kind == kind and found.frames_used == 9 and found.frames_ignored == 2
        assert found.x_mm == pytest.approx(where, abs=1e-9) and found.y_mm == pytest.approx(0, abs=1e-9)
    still = pivot([[-22, 0]] * 5, [[22, 0.01]] * 5)  # no axial rotation: the lines are one line
    assert np.isnan(still.x_mm) and still.kind is None and "turn by" in still.reason


def test_rollback():
    flexion = np.array([5, 30, 60, 90, 120, 90, np.nan])
    ap = np.array([2.0, 0.5, -3.0, -6.0, -9.0, -6.5, 0.0])
    back = rollback(flexion, ap)
    assert (back.flexion_min_deg, back.flexion_max_deg) == (5, 120)
    assert back.excursion_mm == pytest.approx(11.0) and back.range_mm == pytest.approx(11.0)


def test_the_left_knee_is_the_mirror_image_of_the_right():
    """A left knee built as the mirror of a right one (its component, its poses) gives the
    same medial and lateral values, medial still at -x."""
    S = np.diag([-1.0, 1.0, 1.0, 1.0])
    right = prepare_femur(*condyles(), np.eye(4))
    vertices, faces = condyles()
    left = prepare_femur(vertices * [-1, 1, 1], faces[:, ::-1], np.eye(4))
    square = np.array([[-60, -60, 0], [60, -60, 0], [60, 60, 0], [-60, 60, 0.0]])
    tray = place_insert(square, np.array([[0, 1, 2], [0, 2, 3]]), np.eye(4))
    tibia = pose_to_matrix([2, -3, 1, 5, 10, -4])
    for pose in poses(10):
        pose = tibia @ pose
        a = condyle_contact(right, pose, tibia, tibial_frame=np.eye(4), side="right", insert=tray)
        b = condyle_contact(left, S @ pose @ S, S @ tibia @ S, tibial_frame=np.eye(4), side="left", insert=tray)
        for name in ("medial", "lateral"):
            # equal up to the fit (a near tie of lowest vertices may start it one vertex over): measured 0.0002 mm
            np.testing.assert_allclose(getattr(b, name).lowest, getattr(a, name).lowest, atol=0.0005)
            assert getattr(b, name).gap_mm == pytest.approx(getattr(a, name).gap_mm, abs=0.0005)
        assert a.medial.lowest[0] < 0 < a.lateral.lowest[0]
        wrong = condyle_contact(left, S @ pose @ S, S @ tibia @ S, tibial_frame=np.eye(4), side="right")
        assert wrong.medial.lowest[0] == pytest.approx(-a.lateral.lowest[0], abs=0.0005)  # read as right: swapped


def test_a_missing_pose_gives_nan():
    femur = prepare_femur(*condyles(resolution=(20, 10)), np.eye(4))
    contact = condyle_contact(femur, np.full((4, 4), np.nan), np.eye(4), tibial_frame=np.eye(4))
    assert np.all(np.isnan(contact.medial.lowest)) and contact.liftoff == ""
