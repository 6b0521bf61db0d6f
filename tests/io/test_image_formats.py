"""Compressed TIFFs, multi-frame and compressed DICOM, lazy video frames, header size limits."""
from __future__ import annotations

import struct
import zlib

import cv2
import numpy as np
import pytest
import tifffile

from fluorogui.io.dicom import dicom_starting_view
from fluorogui.io.errors import InputError
from fluorogui.io.images import (
    MAX_IMAGE_SIDE_PX,
    frame_count,
    frame_reference,
    image_info,
    read_frame,
    read_image,
    split_frame_reference,
)


def error_of(call, *args):
    with pytest.raises(InputError) as info:
        call(*args)
    return str(info.value)


def gradient(dtype, shape=(48, 64)):
    top = np.iinfo(dtype).max
    return (np.arange(np.prod(shape)).reshape(shape) * top // (np.prod(shape) - 1)).astype(dtype)


@pytest.mark.parametrize("compression", ["lzw", "zlib", "packbits"])
@pytest.mark.parametrize("dtype", [np.uint8, np.uint16])
def test_lossless_tiff_compressions_exact(tmp_path, compression, dtype):
    pixels = gradient(dtype)
    tifffile.imwrite(tmp_path / "c.tif", pixels, compression=compression)
    image = read_image(tmp_path / "c.tif")
    np.testing.assert_array_equal(np.round(image.astype(np.float64) * np.iinfo(dtype).max), pixels)
    info = image_info(tmp_path / "c.tif")
    assert (info.width, info.height, info.frames, info.bits) == (64, 48, 1, np.iinfo(dtype).bits)


def test_jpeg_tiff_8_and_12_bit(tmp_path):
    # lossy: 8-bit within 3 levels; 12-bit samples (JPEG's deep mode) in 16-bit words within 8 levels
    for pixels, top, levels in ((gradient(np.uint8), 255, 3), (gradient(np.uint16) >> 4, 65535, 8)):
        tifffile.imwrite(tmp_path / "j.tif", pixels, compression="jpeg")
        image = read_image(tmp_path / "j.tif").astype(np.float64) * top
        assert np.abs(image - pixels).max() <= levels


def test_png_header_bit_depth(tmp_path):
    cv2.imwrite(str(tmp_path / "a.png"), gradient(np.uint16))
    cv2.imwrite(str(tmp_path / "b.png"), gradient(np.uint8))
    assert image_info(tmp_path / "a.png").describe() == "PNG 64x48, 16-bit"
    assert image_info(tmp_path / "b.png").describe() == "PNG 64x48, 8-bit"


def test_16_bit_keeps_every_level(tmp_path):
    pixels = np.arange(30000, 30000 + 48 * 64, dtype=np.uint16).reshape(48, 64)  # one level apart
    tifffile.imwrite(tmp_path / "deep.tif", pixels, compression="lzw")
    image = read_image(tmp_path / "deep.tif")
    assert len(np.unique(image)) == pixels.size


def test_tiff_stack_frames(tmp_path):
    stack = np.stack([np.full((8, 10), 40 * k, np.uint8) for k in range(4)])
    tifffile.imwrite(tmp_path / "stack.tif", stack, photometric="minisblack")
    assert frame_count(tmp_path / "stack.tif") == 4
    np.testing.assert_allclose(read_image(frame_reference(tmp_path / "stack.tif", 2)), 80 / 255, atol=1e-6)
    assert "4 frames; frame 4 does not exist" in error_of(read_frame, tmp_path / "stack.tif", 4)


def make_dicom(path, frames, syntax=None, geometry=False, pixel_data=True):
    import copy

    from pydicom.dataset import Dataset, FileMetaDataset
    from pydicom.uid import ExplicitVRLittleEndian, XRayAngiographicImageStorage, generate_uid

    meta = FileMetaDataset()
    meta.MediaStorageSOPClassUID = XRayAngiographicImageStorage
    meta.MediaStorageSOPInstanceUID = generate_uid()
    meta.TransferSyntaxUID = ExplicitVRLittleEndian
    ds = Dataset()
    ds.file_meta = meta
    ds.SOPClassUID = XRayAngiographicImageStorage
    ds.SOPInstanceUID = meta.MediaStorageSOPInstanceUID
    ds.Rows, ds.Columns = frames.shape[-2:]
    ds.SamplesPerPixel = 1
    ds.PhotometricInterpretation = "MONOCHROME2"
    ds.BitsAllocated, ds.BitsStored, ds.HighBit, ds.PixelRepresentation = 16, 12, 11, 0
    if frames.ndim == 3:
        ds.NumberOfFrames = frames.shape[0]
    if geometry:
        ds.DistanceSourceToDetector = 1100.0
        ds.DistanceSourceToPatient = 800.0
        ds.ImagerPixelSpacing = [0.30, 0.25]  # row spacing, column spacing
    if pixel_data:
        ds.PixelData = frames.astype("<u2").tobytes()
        if syntax is not None:
            ds = copy.deepcopy(ds)
            ds.compress(syntax)
    ds.save_as(path, enforce_file_format=True)


def twelve_bit_frames(n=3, shape=(32, 40)):
    return (np.arange(n * shape[0] * shape[1]).reshape(n, *shape) * 7 % 4096).astype(np.uint16)


@pytest.mark.parametrize("syntax_name", ["uncompressed", "RLELossless", "JPEG2000Lossless"])
def test_multiframe_dicom_frames_exact(tmp_path, syntax_name):
    import pydicom.uid

    frames = twelve_bit_frames()
    syntax = None if syntax_name == "uncompressed" else getattr(pydicom.uid, syntax_name)
    make_dicom(tmp_path / "run.dcm", frames, syntax)
    info = image_info(tmp_path / "run.dcm")
    assert (info.format, info.width, info.height, info.frames, info.bits) == ("DICOM", 40, 32, 3, 12)
    for k in range(3):
        image = read_image(f"{tmp_path / 'run.dcm'}@{k}")
        np.testing.assert_array_equal(np.round(image.astype(np.float64) * 4095), frames[k])
    assert "3 frames" in error_of(read_image, tmp_path / "run.dcm")
    assert "frame 3 does not exist" in error_of(read_image, f"{tmp_path / 'run.dcm'}@3")


def test_dicom_without_pixel_data(tmp_path):
    make_dicom(tmp_path / "report.dcm", twelve_bit_frames(1)[0], pixel_data=False)
    message = error_of(read_image, tmp_path / "report.dcm")
    assert message.startswith(str(tmp_path / "report.dcm")) and "no pixel data" in message


def test_dicom_starting_view_from_header(tmp_path):
    make_dicom(tmp_path / "g.dcm", twelve_bit_frames(1)[0], geometry=True)
    view = dicom_starting_view(tmp_path / "g.dcm")
    assert view.distance == 1100.0 and view.pitch == (0.25, 0.30)
    np.testing.assert_allclose(view.source, [0, 0, 800])
    # the isocentre projects to the image centre; 1 mm there spans 1100/800 mm on the detector
    uv = view.project(np.array([[0.0, 0.0, 0.0], [1.0, 0.0, 0.0]]))
    np.testing.assert_allclose(uv[0], [(40 - 1) / 2, (32 - 1) / 2])
    assert uv[1, 0] - uv[0, 0] == pytest.approx(1100 / 800 / 0.25)
    make_dicom(tmp_path / "plain.dcm", twelve_bit_frames(1)[0])
    assert dicom_starting_view(tmp_path / "plain.dcm") is None
    # offered wherever a calibration is taken
    from fluorogui.io.calibration import load_view

    offered = load_view(tmp_path / "g.dcm")
    assert offered.extra["starting_geometry"] and offered.to_dict() == {**view.to_dict(), "name": "g"}
    with pytest.raises(InputError, match="gives no view geometry"):
        load_view(tmp_path / "plain.dcm")


def write_video(path, levels, size=(32, 24), fourcc="MJPG"):
    writer = cv2.VideoWriter(str(path), cv2.VideoWriter_fourcc(*fourcc), 10, size, isColor=False)
    if not writer.isOpened():
        pytest.skip(f"OpenCV has no {fourcc} writer here")
    for level in levels:
        writer.write(np.full(size[::-1], level, np.uint8))
    writer.release()


def test_video_frames_lazily_in_any_order(tmp_path):
    levels = [10 * k for k in range(20)]
    write_video(tmp_path / "run.avi", levels)
    info = image_info(tmp_path / "run.avi")
    assert (info.width, info.height, info.frames) == (32, 24, 20) and "MJPG" in info.detail
    for k in (0, 1, 2, 15, 3, 19, 19, 0):  # in order, jumps forward and back
        assert abs(float(read_image(frame_reference(tmp_path / "run.avi", k)).mean()) - levels[k] / 255) < 0.02
    assert "frame 25 does not exist" in error_of(read_image, f"{tmp_path / 'run.avi'}@25")


def test_unreadable_video(tmp_path):
    (tmp_path / "clip.mp4").write_bytes(b"\x00\x00\x00\x18ftypmp42" + b"garbage" * 200)
    message = error_of(read_image, f"{tmp_path / 'clip.mp4'}@0")
    assert message.startswith(str(tmp_path / "clip.mp4")) and "codec" in message


def test_frame_reference_parsing(tmp_path):
    assert split_frame_reference(tmp_path / "a.dcm@12") == (tmp_path / "a.dcm", 12)
    literal = tmp_path / "odd@3.png"
    cv2.imwrite(str(literal), np.zeros((4, 4), np.uint8))
    assert split_frame_reference(literal) == (literal, None)
    assert read_image(literal).shape == (4, 4)
    assert error_of(read_image, tmp_path / "gone.avi@0") == f"{tmp_path / 'gone.avi'}: file not found"


def _png_chunk(kind: bytes, data: bytes) -> bytes:
    return struct.pack(">I", len(data)) + kind + data + struct.pack(">I", zlib.crc32(kind + data))


def test_oversized_headers_refused_before_decoding(tmp_path):
    huge = MAX_IMAGE_SIDE_PX * 2 + 1
    png = tmp_path / "huge.png"  # a 50 KB-ish PNG claiming huge x huge pixels
    png.write_bytes(b"\x89PNG\r\n\x1a\n" + _png_chunk(b"IHDR", struct.pack(">IIBBBBB", huge, huge, 8, 0, 0, 0, 0))
                    + _png_chunk(b"IDAT", zlib.compress(b"\x00" * 1000)) + _png_chunk(b"IEND", b""))
    tifffile.imwrite(tmp_path / "huge.tif", np.zeros((16, 16), np.uint8))
    with tifffile.TiffFile(tmp_path / "huge.tif", mode="r+b") as tif:
        tif.pages[0].tags["ImageWidth"].overwrite(40000)
        tif.pages[0].tags["ImageLength"].overwrite(40000)
    make_dicom(tmp_path / "huge.dcm", np.zeros((4, 4), np.uint16))
    import pydicom

    ds = pydicom.dcmread(tmp_path / "huge.dcm")
    ds.Rows = ds.Columns = 40000
    ds.save_as(tmp_path / "huge.dcm")
    for name in ("huge.png", "huge.tif", "huge.dcm"):
        message = error_of(read_image, tmp_path / name)
        assert message.startswith(str(tmp_path / name)) and "over the limit" in message and "16384" in message


def test_jpeg_baseline_multiframe_dicom(tmp_path):
    """8-bit JPEG-compressed XA runs (the common lossy fluoroscopy export) decode frame by frame."""
    from pydicom.dataset import Dataset, FileMetaDataset
    from pydicom.encaps import encapsulate
    from pydicom.uid import JPEGBaseline8Bit, XRayAngiographicImageStorage, generate_uid

    frames = [np.tile(np.linspace(20 + 60 * k, 200, 40, dtype=np.uint8), (32, 1)) for k in range(3)]
    meta = FileMetaDataset()
    meta.MediaStorageSOPClassUID = XRayAngiographicImageStorage
    meta.MediaStorageSOPInstanceUID = generate_uid()
    meta.TransferSyntaxUID = JPEGBaseline8Bit
    ds = Dataset()
    ds.file_meta = meta
    ds.SOPClassUID, ds.SOPInstanceUID = XRayAngiographicImageStorage, meta.MediaStorageSOPInstanceUID
    ds.Rows, ds.Columns, ds.NumberOfFrames = 32, 40, 3
    ds.SamplesPerPixel, ds.PhotometricInterpretation = 1, "MONOCHROME2"
    ds.BitsAllocated, ds.BitsStored, ds.HighBit, ds.PixelRepresentation = 8, 8, 7, 0
    ds.PixelData = encapsulate([cv2.imencode(".jpg", f, [cv2.IMWRITE_JPEG_QUALITY, 95])[1].tobytes() for f in frames])
    ds["PixelData"].VR = "OB"
    ds.save_as(tmp_path / "xa.dcm", enforce_file_format=True)
    info = image_info(tmp_path / "xa.dcm")
    assert info.frames == 3 and "JPEG" in info.detail
    for k in range(3):
        image = read_image(frame_reference(tmp_path / "xa.dcm", k)) * 255.0
        assert np.abs(image - frames[k]).max() <= 3  # lossy at quality 95
