"""One calibrated view is a valid session: `match` with one camera, FILE@N frames, and the
comparison with JointTrack's own poses on the real single-plane data."""
from __future__ import annotations

import json

import numpy as np
import pytest

from fluorogui.cli import main
from fluorogui.core.projection.mesh import prepare_mesh
from fluorogui.core.projection.pose import transform_points
from fluorogui.io.calibration import jointtrack_to_pose, load_jointtrack_poses, save_view_json
from fluorogui.simulation.phantoms import femoral_component_mesh
from fluorogui.simulation.protocols import dual_orthogonal_views, flexion_pose
from fluorogui.simulation.render import render_fluoro
from fluorogui.workflow.messages import SINGLE_PLANE_NOTE


def _write_stl(path, vertices, faces):
    import pyvista as pv

    pv.PolyData(vertices, np.column_stack([np.full(len(faces), 3), faces]).ravel()).save(str(path))


def _write_run(path, frames_unit):
    """A 16-bit multi-frame DICOM (XA) of float frames in [0, 1]."""
    from pydicom.dataset import Dataset, FileMetaDataset
    from pydicom.uid import ExplicitVRLittleEndian, XRayAngiographicImageStorage, generate_uid

    frames = np.round(np.clip(frames_unit, 0, 1) * 65535).astype("<u2")
    meta = FileMetaDataset()
    meta.MediaStorageSOPClassUID = XRayAngiographicImageStorage
    meta.MediaStorageSOPInstanceUID = generate_uid()
    meta.TransferSyntaxUID = ExplicitVRLittleEndian
    ds = Dataset()
    ds.file_meta = meta
    ds.SOPClassUID, ds.SOPInstanceUID = XRayAngiographicImageStorage, meta.MediaStorageSOPInstanceUID
    ds.Rows, ds.Columns = frames.shape[1:]
    ds.NumberOfFrames = frames.shape[0]
    ds.SamplesPerPixel, ds.PhotometricInterpretation = 1, "MONOCHROME2"
    ds.BitsAllocated, ds.BitsStored, ds.HighBit, ds.PixelRepresentation = 16, 16, 15, 0
    ds.PixelData = frames.tobytes()
    ds.save_as(path, enforce_file_format=True)


def test_single_view_match_on_a_dicom_frame(tmp_path, capsys):
    v, f = femoral_component_mesh()
    mesh = prepare_mesh(v, f)
    truth = flexion_pose(v, 45.0)
    view = dual_orthogonal_views()[0]
    image = render_fluoro(view, [(transform_points(truth, mesh.vertices), mesh.faces)], np.random.default_rng(1))
    blank = np.full_like(image, 0.8)
    _write_run(tmp_path / "run.dcm", np.stack([blank, image, blank]))
    save_view_json(view, tmp_path / "cam.json")
    _write_stl(tmp_path / "femur.stl", v, f)
    start = truth + np.array([2.0, -2.0, 1.5, 3.0, -2.0, 2.0])
    code = main(["match", "--camera", str(tmp_path / "cam.json"), "--image", f"{tmp_path / 'run.dcm'}@1",
                 "--model", str(tmp_path / "femur.stl"), "--start", *map(str, start), "--json"])
    captured = capsys.readouterr()
    assert code == 0 and SINGLE_PLANE_NOTE in captured.err
    out = json.loads(captured.out)
    centroid = mesh.centroid
    moved = transform_points(np.array(out["pose"]), centroid[None])[0] - transform_points(truth, centroid[None])[0]
    along_beam = float(moved @ view.normal)
    in_plane = moved - along_beam * view.normal
    assert np.linalg.norm(in_plane) < 0.0058, moved  # measured 0.0029 mm
    assert abs(along_beam) < 0.043, moved  # the weak direction: measured 0.0216 mm on this clean image
    assert np.all(np.abs(np.array(out["pose"][3:]) - truth[3:]) < 0.019)  # measured 0.0093 deg


@pytest.mark.parametrize("component, mesh_name, poses", [("femoral", "KR_right_7_fem.stl", "fem.jts"),
                                                          ("tibial", "KR_right_6_tib.stl", "tib.jts")])
def test_real_single_plane_against_jointtrack(shared_data, capsys, component, mesh_name, poses):
    folder = shared_data / "single-plane-tka"
    reference = jointtrack_to_pose(load_jointtrack_poses(folder / poses)[0])
    code = main(["match", "--camera", str(folder / "calibration.txt"), "--image", str(folder / "AT_K1_V1_0160.tif"),
                 "--model", str(folder / mesh_name), "--start", *map(str, reference), "--json"])
    out = json.loads(capsys.readouterr().out)
    assert code == 0
    difference = np.array(out["pose"]) - reference
    # JointTrack's camera frame: x, y in the image plane, z along the beam (the weak direction)
    assert np.all(np.abs(difference[:2]) < 1.0), difference  # measured 0.2 (femur), 0.64 mm (tibia)
    assert abs(difference[2]) < 20.0, difference  # measured 5.7 (femur), 15.2 mm (tibia)
    assert np.all(np.abs(difference[3:]) < 1.45), difference  # measured up to 0.73 deg (tibia)


def test_import_single_plane_explicit_files(shared_data, tmp_path, capsys):
    from fluorogui.io.project.document import load_project

    folder = shared_data / "single-plane-tka"
    out = tmp_path / "single.fluoro"
    assert main(["import", "--out", str(out), "--camera", str(folder / "calibration.txt"), "--images1", str(folder),
                 "--model", f"femoral={folder / 'KR_right_7_fem.stl'}"]) == 0
    project = load_project(out)
    assert len(project.views) == 1 and project.frames == [0, 1, 2]
    assert [m.component for m in project.models] == ["femoral"]
    assert main(["import", "--out", str(tmp_path / "x.fluoro"), "--camera", str(folder / "calibration.txt"),
                 "--images1", str(folder), "--images2", str(folder),
                 "--model", f"femoral={folder / 'KR_right_7_fem.stl'}"]) == 2
    assert "--images1 only" in capsys.readouterr().err
