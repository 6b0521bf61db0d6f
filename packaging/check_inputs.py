"""Inputs of ``packaging/build.py --check``, generated at check time (deterministic; nothing
is downloaded or stored in the repository).

``write_scene``: a two-view scene of the procedural femoral component at 45 degrees flexion,
one view an LZW-compressed 16-bit TIFF (imagecodecs, loaded by importlib) and the other a
JPEG Lossless 16-bit DICOM (decoded by the pylibjpeg-libjpeg plugin, found through its
entry points), and the arguments of a headless ``match`` from a start 4 mm / 5 degrees off.
``write_format_probes``: more compressed files the readers accept (JPEG and Deflate TIFF,
JPEG baseline and JPEG 2000 DICOM) that the built program must read exactly as the
installed one does.
"""
from __future__ import annotations

from pathlib import Path

import numpy as np


def _uint16(image) -> np.ndarray:
    """A [0, 1] float image as 16-bit pixels, rounded the way ``write_image`` does."""
    return np.round(np.clip(np.asarray(image, dtype=float), 0.0, 1.0) * 65535).astype(np.uint16)


def write_lzw_tiff(path: Path, pixels: np.ndarray) -> Path:
    import tifffile

    tifffile.imwrite(path, pixels, compression="lzw", predictor=True)
    return path


def write_dicom(path: Path, frame_bytes: bytes, shape, bits: int, syntax) -> Path:
    """A one-frame XA DICOM of already-encoded pixel data in ``syntax``."""
    from pydicom.dataset import Dataset, FileMetaDataset
    from pydicom.encaps import encapsulate
    from pydicom.uid import XRayAngiographicImageStorage

    meta = FileMetaDataset()
    meta.MediaStorageSOPClassUID = XRayAngiographicImageStorage
    meta.MediaStorageSOPInstanceUID = "1.2.826.0.1.3680043.8.498.1"
    meta.TransferSyntaxUID = syntax
    ds = Dataset()
    ds.file_meta = meta
    ds.SOPClassUID, ds.SOPInstanceUID = XRayAngiographicImageStorage, meta.MediaStorageSOPInstanceUID
    ds.Rows, ds.Columns = shape
    ds.SamplesPerPixel, ds.PhotometricInterpretation = 1, "MONOCHROME2"
    ds.BitsAllocated, ds.BitsStored, ds.HighBit, ds.PixelRepresentation = (8 if bits <= 8 else 16), bits, bits - 1, 0
    ds.PixelData = encapsulate([frame_bytes])
    ds["PixelData"].VR = "OB"
    ds.save_as(path, enforce_file_format=True)
    return path


def write_jpeg_lossless_dicom(path: Path, pixels: np.ndarray) -> Path:
    """16-bit JPEG Lossless, first-order prediction (Process 14 SV1), as fluoroscopes export."""
    import imagecodecs
    from pydicom.uid import JPEGLosslessSV1

    data = imagecodecs.jpeg8_encode(pixels, lossless=True, predictor=1, bitspersample=16)
    return write_dicom(path, data, pixels.shape, 16, JPEGLosslessSV1)


def write_scene(folder: Path) -> tuple[list[str], list[float]]:
    """The scene's files in ``folder``; the match arguments and the true pose."""
    import pyvista as pv

    from fluorogui.core.projection.mesh import prepare_mesh
    from fluorogui.core.projection.pose import transform_points
    from fluorogui.io.calibration import save_view_json
    from fluorogui.simulation.phantoms import femoral_component_mesh
    from fluorogui.simulation.protocols import dual_orthogonal_views, flexion_pose
    from fluorogui.simulation.render import render_fluoro

    v, f = femoral_component_mesh()
    mesh = prepare_mesh(v, f)
    truth = flexion_pose(v, 45.0)
    world = transform_points(truth, mesh.vertices)
    rng = np.random.default_rng(0)
    writers = (("cam1-lzw.tif", write_lzw_tiff), ("cam2-jpeg-lossless.dcm", write_jpeg_lossless_dicom))
    args = ["match"]
    for k, (view, (name, write)) in enumerate(zip(dual_orthogonal_views(), writers)):
        cam = folder / f"cam{k + 1}.json"
        save_view_json(view, cam)
        image = write(folder / name, _uint16(render_fluoro(view, [(world, mesh.faces)], rng)))
        args += ["--camera", str(cam), "--image", str(image)]
    model = folder / "femur.stl"
    pv.PolyData(v, np.column_stack([np.full(len(f), 3), f]).ravel()).save(str(model))
    start = truth + np.array([4.0, -3.0, 2.0, 5.0, -4.0, 3.0])
    args += ["--model", str(model), "--start", *[f"{x:.6f}" for x in start], "--json"]
    return args, [float(x) for x in truth]


def write_format_probes(folder: Path) -> list[Path]:
    """Small files in the other compressions the readers accept."""
    import imagecodecs
    import tifffile
    from pydicom.uid import JPEG2000Lossless, JPEGBaseline8Bit

    y, x = np.mgrid[0:96, 0:128]
    smooth = (np.sin(x / 9.0) * np.cos(y / 13.0) + 1.0) / 2.0
    eight, sixteen = np.round(smooth * 255).astype(np.uint8), _uint16(smooth)
    paths = [folder / "probe-jpeg.tif", folder / "probe-deflate.tif"]
    tifffile.imwrite(paths[0], eight, compression="jpeg")
    tifffile.imwrite(paths[1], sixteen, compression="zlib", predictor=True)
    paths.append(write_dicom(folder / "probe-jpeg-baseline.dcm", imagecodecs.jpeg8_encode(eight, level=90),
                             eight.shape, 8, JPEGBaseline8Bit))
    j2k = imagecodecs.jpeg2k_encode(sixteen, level=0, codecformat="J2K")  # level 0: lossless
    paths.append(write_dicom(folder / "probe-jpeg2000.dcm", j2k, sixteen.shape, 16, JPEG2000Lossless))
    return paths
