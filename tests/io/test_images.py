"""Image and video reading: every format to 2D float32 in [0, 1], and the bad-input messages."""
from __future__ import annotations

from pathlib import Path

import cv2
import numpy as np
import pytest
import tifffile

from fluorogui.io.errors import InputError
from fluorogui.io.images import read_image, read_video_frames, write_image

DATA = Path(__file__).resolve().parents[2].parent / "shared" / "data"


def ramp(dtype, shape=(12, 16)):
    top = np.iinfo(dtype).max
    return (np.arange(np.prod(shape)).reshape(shape) * top // (np.prod(shape) - 1)).astype(dtype)


def assert_unit_gray(image, shape=(12, 16)):
    assert image.dtype == np.float32 and image.shape == shape
    assert image.min() >= 0.0 and image.max() <= 1.0


def error_of(call, *args):
    with pytest.raises(InputError) as info:
        call(*args)
    message = str(info.value)
    assert message.startswith(f"{args[0]}: ") and "\n" not in message
    return message


@pytest.mark.parametrize("dtype", [np.uint8, np.uint16])
@pytest.mark.parametrize("suffix", [".tif", ".png"])
def test_integer_images_scaled_by_type_range(tmp_path, dtype, suffix):
    pixels = ramp(dtype)
    path = tmp_path / f"img{suffix}"
    if suffix == ".tif":
        tifffile.imwrite(path, pixels)
    else:
        cv2.imwrite(str(path), pixels)
    image = read_image(path)
    assert_unit_gray(image)
    np.testing.assert_allclose(image, pixels / np.iinfo(dtype).max, atol=1e-6)


def test_jpeg_and_bmp(tmp_path):
    pixels = np.full((12, 16), 128, np.uint8)
    for suffix in (".jpg", ".bmp"):
        path = tmp_path / f"img{suffix}"
        cv2.imwrite(str(path), pixels)
        image = read_image(path)
        assert_unit_gray(image)
        assert abs(float(image.mean()) - 128 / 255) < 0.01


def test_float_tiff_clipped(tmp_path):
    pixels = np.linspace(-0.5, 1.5, 12 * 16, dtype=np.float32).reshape(12, 16)
    tifffile.imwrite(tmp_path / "f.tif", pixels)
    image = read_image(tmp_path / "f.tif")
    np.testing.assert_allclose(image, np.clip(pixels, 0, 1))


def test_rgb_becomes_gray(tmp_path):
    rgb = np.zeros((12, 16, 3), np.uint8)
    rgb[..., 0] = 255  # pure red
    tifffile.imwrite(tmp_path / "rgb.tif", rgb, photometric="rgb")
    cv2.imwrite(str(tmp_path / "rgb.png"), rgb[..., ::-1])  # OpenCV writes BGR
    for name in ("rgb.tif", "rgb.png"):
        image = read_image(tmp_path / name)
        assert_unit_gray(image)
        np.testing.assert_allclose(image, 0.299, atol=1e-6)


def write_dicom(path, pixels, photometric="MONOCHROME2", slope=1.0, intercept=0.0, bits=16):
    from pydicom.dataset import Dataset, FileMetaDataset
    from pydicom.uid import ExplicitVRLittleEndian, SecondaryCaptureImageStorage, generate_uid

    meta = FileMetaDataset()
    meta.MediaStorageSOPClassUID = SecondaryCaptureImageStorage
    meta.MediaStorageSOPInstanceUID = generate_uid()
    meta.TransferSyntaxUID = ExplicitVRLittleEndian
    ds = Dataset()
    ds.file_meta = meta
    ds.SOPClassUID = SecondaryCaptureImageStorage
    ds.SOPInstanceUID = meta.MediaStorageSOPInstanceUID
    ds.Rows, ds.Columns = pixels.shape[-2:]
    ds.SamplesPerPixel = 1
    ds.PhotometricInterpretation = photometric
    ds.BitsAllocated = 16
    ds.BitsStored = bits
    ds.HighBit = bits - 1
    ds.PixelRepresentation = 0
    if pixels.ndim == 3:
        ds.NumberOfFrames = pixels.shape[0]
    ds.RescaleSlope = slope
    ds.RescaleIntercept = intercept
    ds.PixelData = pixels.astype("<u2").tobytes()
    ds.save_as(path, enforce_file_format=True)


def test_dicom_monochrome2_and_1(tmp_path):
    pixels = np.array([[0, 1023], [2047, 4095]], np.uint16)
    write_dicom(tmp_path / "a.dcm", pixels, bits=12)
    write_dicom(tmp_path / "b.dcm", pixels, photometric="MONOCHROME1", bits=12)
    a, b = read_image(tmp_path / "a.dcm"), read_image(tmp_path / "b.dcm")
    assert a.dtype == np.float32 and a.shape == (2, 2)
    np.testing.assert_allclose(a, pixels / 4095, atol=1e-6)
    np.testing.assert_allclose(b, 1 - pixels / 4095, atol=1e-6)


def test_dicom_rescale_keeps_relative_scale(tmp_path):
    pixels = np.array([[0, 100], [200, 255]], np.uint16)
    write_dicom(tmp_path / "r.dcm", pixels, slope=2.0, intercept=-1000.0, bits=8)
    np.testing.assert_allclose(read_image(tmp_path / "r.dcm"), pixels / 255, atol=1e-6)


def test_dicom_detected_without_extension(tmp_path):
    write_dicom(tmp_path / "IM0001", np.array([[0, 255]], np.uint16), bits=8)
    np.testing.assert_allclose(read_image(tmp_path / "IM0001"), [[0, 1]])


def test_dicom_multiframe_refused(tmp_path):
    write_dicom(tmp_path / "m.dcm", np.zeros((3, 4, 4), np.uint16), bits=8)
    assert "3 frames" in error_of(read_image, tmp_path / "m.dcm")


def test_write_image_round_trip(tmp_path):
    image = np.linspace(0, 1, 12 * 16).reshape(12, 16)
    for name, bits, tol in (("a.png", 8, 0.5 / 255), ("b.png", 16, 0.5 / 65535), ("c.tif", 16, 0.5 / 65535)):
        write_image(tmp_path / name, image, bits=bits)
        np.testing.assert_allclose(read_image(tmp_path / name), image, atol=tol + 1e-7)
    assert "2D grayscale" in error_of(write_image, tmp_path / "d.png", np.zeros((2, 2, 3)))
    assert "PNG or TIFF" in error_of(write_image, tmp_path / "e.jpg", image)


def test_video_frames(tmp_path):
    path = tmp_path / "clip.avi"
    writer = cv2.VideoWriter(str(path), cv2.VideoWriter_fourcc(*"MJPG"), 10, (32, 24), isColor=False)
    if not writer.isOpened():
        pytest.skip("OpenCV has no AVI writer here")
    for level in (0, 100, 200):
        writer.write(np.full((24, 32), level, np.uint8))
    writer.release()
    frames = read_video_frames(path)
    assert len(frames) == 3
    assert all(f.shape == (24, 32) and f.dtype == np.float32 for f in frames)
    picked = read_video_frames(path, [2, 0])
    assert abs(float(picked[0].mean()) - 200 / 255) < 0.03 and float(picked[1].mean()) < 0.03
    assert "frame 7 does not exist" in error_of(read_video_frames, path, [7])


def test_real_tiff():
    path = DATA / "biplane-tka" / "cam1" / "000000.tif"
    if not path.exists():
        pytest.skip("shared data not available")
    image = read_image(path)
    assert image.shape == (1024, 1024) and image.dtype == np.float32
    assert 0 <= image.min() < image.max() <= 1


# -- bad inputs -----------------------------------------------------------------------------------------
def test_missing_empty_unsupported(tmp_path):
    assert error_of(read_image, tmp_path / "none.png").endswith("file not found")
    (tmp_path / "empty.png").write_bytes(b"")
    assert error_of(read_image, tmp_path / "empty.png").endswith("file is empty")
    (tmp_path / "notes.txt").write_text("hello")
    assert "unsupported image type '.txt'" in error_of(read_image, tmp_path / "notes.txt")
    assert "is a folder" in error_of(read_image, tmp_path)
    assert "unsupported video type" in error_of(read_video_frames, tmp_path / "notes.txt")


def test_corrupt_and_truncated(tmp_path):
    (tmp_path / "junk.png").write_bytes(b"this is not a png at all" * 10)
    assert "corrupt or unreadable PNG" in error_of(read_image, tmp_path / "junk.png")
    pixels = (np.random.default_rng(0).random((64, 64)) * 255).astype(np.uint8)
    for suffix in (".png", ".jpg"):
        whole = tmp_path / f"whole{suffix}"
        cv2.imwrite(str(whole), pixels)
        cut = tmp_path / f"cut{suffix}"
        cut.write_bytes(whole.read_bytes()[: whole.stat().st_size * 2 // 3])
        message = error_of(read_image, cut)
        assert "truncated" in message or "corrupt" in message
    tifffile.imwrite(tmp_path / "whole.tif", pixels)
    (tmp_path / "cut.tif").write_bytes((tmp_path / "whole.tif").read_bytes()[:100])
    assert "corrupt or truncated TIFF" in error_of(read_image, tmp_path / "cut.tif")
    (tmp_path / "junk.avi").write_bytes(b"nothing" * 100)
    assert "video" in error_of(read_video_frames, tmp_path / "junk.avi")
    (tmp_path / "junk.dcm").write_bytes(b"nothing" * 100)
    assert "DICOM" in error_of(read_image, tmp_path / "junk.dcm")


def test_damaged_jpegs_with_their_end_marker_are_refused(tmp_path):
    """Cut short (its end marker put back) or with scan data overwritten, a JPEG still
    decodes: libjpeg fills what is missing with grey and only prints a warning (issue 44:
    such a file was matched as an ordinary image). The warning refuses it; a harmless one
    (extraneous bytes before a marker) does not."""
    pixels = (np.random.default_rng(0).random((64, 96)) * 255).astype(np.uint8)
    whole = cv2.imencode(".jpg", pixels)[1].tobytes()
    progressive = cv2.imencode(".jpg", pixels, [cv2.IMWRITE_JPEG_PROGRESSIVE, 1])[1].tobytes()
    garbled = bytearray(whole)
    garbled[len(garbled) // 2: len(garbled) // 2 + 40] = bytes(range(200, 240))
    for name, data in (("cut.jpg", whole[: len(whole) // 2] + b"\xff\xd9"), ("garbled.jpg", bytes(garbled)),
                       ("progressive.jpg", progressive[: len(progressive) // 2] + b"\xff\xd9")):
        (tmp_path / name).write_bytes(data)
        message = error_of(read_image, tmp_path / name)
        assert "damaged JPEG image: the decoder reports 'Corrupt JPEG data:" in message, message
    (tmp_path / "whole.jpg").write_bytes(whole)
    (tmp_path / "extra.jpg").write_bytes(whole[:-2] + b"\x00\x00\xff\xd9")  # 2 bytes before the end marker
    for name in ("whole.jpg", "extra.jpg"):
        np.testing.assert_array_equal(read_image(tmp_path / name), read_image(tmp_path / "whole.jpg"))


def test_blank_images_are_refused_for_matching_but_a_dark_one_is_not(tmp_path):
    from fluorogui.io.images import check_not_blank

    for name, pixels, words in (("zero.tif", np.zeros((8, 8), np.uint8), "every pixel 0)"),
                                ("full.png", np.full((8, 8), 65535, np.uint16), "every pixel 65535 of 65535)")):
        path = tmp_path / name
        tifffile.imwrite(path, pixels) if name.endswith(".tif") else cv2.imwrite(str(path), pixels)
        image = read_image(path)  # read (and shown): only matching refuses it
        with pytest.raises(InputError) as info:
            check_not_blank(image, path)
        assert str(info.value) == f"{path}: the image is blank ({words}: it shows nothing to match"
    dark = np.zeros((8, 8), np.uint8)
    dark[3, 4] = 1  # one pixel different: dark, not blank
    tifffile.imwrite(tmp_path / "dark.tif", dark)
    check_not_blank(read_image(tmp_path / "dark.tif"), tmp_path / "dark.tif")


def test_stack_refused(tmp_path):
    tifffile.imwrite(tmp_path / "stack.tif", np.zeros((3, 8, 8), np.uint8), photometric="minisblack")
    assert "stack of 3 frames" in error_of(read_image, tmp_path / "stack.tif")
    volume = np.zeros((2, 8, 8), np.uint8)
    tifffile.imwrite(tmp_path / "planes.tif", volume, photometric="minisblack", metadata=None, contiguous=True)
    message = error_of(read_image, tmp_path / "planes.tif")
    assert "stack" in message or "3D" in message


def test_planar_rgb_tiff(tmp_path):
    planes = np.zeros((3, 8, 8), np.uint8)
    planes[0] = 255
    tifffile.imwrite(tmp_path / "planar.tif", planes, photometric="rgb", planarconfig="separate")
    np.testing.assert_allclose(read_image(tmp_path / "planar.tif"), 0.299, atol=1e-6)
