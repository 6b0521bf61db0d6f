"""Read fluoroscopic images and videos as 2D grayscale float32 arrays in [0, 1]; write images.

Integer images are scaled by their type's full range (8-bit / 255, 16-bit / 65535), so a
sequence keeps one intensity scale from frame to frame. DICOM pixel data get their rescale
slope / intercept and are scaled by the stored bit range; MONOCHROME1 is inverted so bone
and metal look the same as in the other formats. Colour images become luminance.
"""
from __future__ import annotations

from pathlib import Path

import cv2
import numpy as np

from fluorogui.io.errors import InputError, check_input_file, describe_os_error

TIFF_SUFFIXES = (".tif", ".tiff")
CV2_SUFFIXES = (".png", ".jpg", ".jpeg", ".bmp")
DICOM_SUFFIXES = (".dcm", ".dicom")
VIDEO_SUFFIXES = (".avi", ".mp4", ".mov", ".mkv")
IMAGE_SUFFIXES = TIFF_SUFFIXES + CV2_SUFFIXES + DICOM_SUFFIXES

_LUMA_RGB = np.array([0.299, 0.587, 0.114])


# -- reading ------------------------------------------------------------------------------------
def read_image(path) -> np.ndarray:
    """One image file as a 2D float32 array in [0, 1] (rows, columns)."""
    path = Path(path)
    _check_file(path)
    suffix = path.suffix.lower()
    if suffix in TIFF_SUFFIXES:
        pixels, channel_order = _read_tiff(path), "rgb"
    elif suffix in CV2_SUFFIXES:
        pixels, channel_order = _read_cv2(path), "bgr"
    elif suffix in DICOM_SUFFIXES or _has_dicom_preamble(path):
        return _read_dicom(path)
    elif suffix in VIDEO_SUFFIXES:
        raise InputError(path, "is a video: import its frames with read_video_frames")
    else:
        raise InputError(
            path, f"unsupported image type '{suffix or '(none)'}' (use TIFF, PNG, JPEG, BMP or DICOM)"
        )
    return _to_unit_gray(path, pixels, channel_order)


def read_video_frames(path, indices=None) -> list[np.ndarray]:
    """Frames of an AVI / MP4 video as 2D float32 arrays in [0, 1].

    ``indices`` selects frames (0-based); None reads them all. An index past the end of the
    video raises InputError.
    """
    path = Path(path)
    _check_file(path)
    if path.suffix.lower() not in VIDEO_SUFFIXES:
        raise InputError(path, f"unsupported video type '{path.suffix or '(none)'}' (use AVI or MP4)")
    capture = cv2.VideoCapture(str(path))
    try:
        if not capture.isOpened():
            raise InputError(path, "cannot open the video (corrupt file or unsupported codec)")
        wanted = None if indices is None else sorted({int(i) for i in indices})
        if wanted is not None and wanted and wanted[0] < 0:
            raise InputError(path, f"frame index {wanted[0]} is negative")
        frames: dict[int, np.ndarray] = {}
        index = 0
        last = None if wanted is None else (wanted[-1] if wanted else -1)
        while last is None or index <= last:
            ok, frame = capture.read()
            if not ok:
                break
            if wanted is None or index in wanted:
                frames[index] = _to_unit_gray(path, frame, "bgr")
            index += 1
    finally:
        capture.release()
    if wanted is None:
        if not frames:
            raise InputError(path, "the video has no readable frames")
        return [frames[i] for i in sorted(frames)]
    missing = [i for i in wanted if i not in frames]
    if missing:
        raise InputError(path, f"the video has {index} readable frames; frame {missing[0]} does not exist")
    order = [int(i) for i in indices]
    return [frames[i] for i in order]


# -- writing --------------------------------------------------------------------------------------
def write_image(path, array, bits: int = 8) -> None:
    """Write a 2D float image in [0, 1] as an 8- or 16-bit grayscale PNG or TIFF."""
    path = Path(path)
    image = np.asarray(array, dtype=float)
    if image.ndim != 2:
        raise InputError(path, f"can only write 2D grayscale images, got shape {image.shape}")
    if bits not in (8, 16):
        raise InputError(path, f"bit depth must be 8 or 16, not {bits}")
    if not np.all(np.isfinite(image)):
        raise InputError(path, "image contains NaN or infinite values")
    top = 255 if bits == 8 else 65535
    pixels = np.round(np.clip(image, 0.0, 1.0) * top).astype(np.uint8 if bits == 8 else np.uint16)
    suffix = path.suffix.lower()
    try:
        if suffix in TIFF_SUFFIXES:
            import tifffile

            tifffile.imwrite(path, pixels)
        elif suffix == ".png":
            if not cv2.imwrite(str(path), pixels):
                raise InputError(path, "could not write the PNG file")
        else:
            raise InputError(path, f"can write PNG or TIFF, not '{suffix or '(none)'}'")
    except OSError as exc:
        raise InputError(path, f"could not save: {describe_os_error(exc)}") from None


# -- format readers ----------------------------------------------------------------------------
def _check_file(path: Path) -> None:
    check_input_file(path, "image file")  # regular files only: a FIFO would block
    try:
        size = path.stat().st_size
    except OSError as exc:
        raise InputError(path, f"cannot read the file: {describe_os_error(exc)}") from None
    if size == 0:
        raise InputError(path, "file is empty")


def _read_tiff(path: Path) -> np.ndarray:
    import tifffile

    try:
        with tifffile.TiffFile(path) as tif:
            if len(tif.pages) > 1:
                raise InputError(
                    path, f"contains a stack of {len(tif.pages)} images; fluorogui needs one 2D image per file"
                )
            page = tif.pages[0]
            _check_claimed_pixels(path, int(np.prod(page.shape, dtype=np.float64)))  # before allocating
            pixels = page.asarray()
            if pixels.ndim == 3 and page.planarconfig == tifffile.PLANARCONFIG.SEPARATE:
                pixels = np.moveaxis(pixels, 0, -1)  # colour planes stored one after another
            return pixels
    except InputError:
        raise
    except OSError as exc:
        raise InputError(path, f"cannot read the file: {describe_os_error(exc)}") from None
    except Exception as exc:  # tifffile raises several types on corrupt data
        raise InputError(path, f"corrupt or truncated TIFF ({type(exc).__name__})") from None


def _read_cv2(path: Path) -> np.ndarray:
    try:
        data = np.fromfile(path, dtype=np.uint8)  # works with non-ASCII paths, unlike cv2.imread
    except OSError as exc:
        raise InputError(path, f"cannot read the file: {describe_os_error(exc)}") from None
    if data[:8].tobytes() == b"\x89PNG\r\n\x1a\n" and data.size >= 24:
        _check_claimed_pixels(path, int.from_bytes(data[16:20].tobytes(), "big") *
                              int.from_bytes(data[20:24].tobytes(), "big"))  # IHDR, before decoding
    pixels = cv2.imdecode(data, cv2.IMREAD_UNCHANGED)
    if pixels is None:
        raise InputError(path, f"corrupt or unreadable {path.suffix.lstrip('.').upper()} image")
    if _looks_truncated(path, data):
        raise InputError(path, f"truncated {path.suffix.lstrip('.').upper()} image")
    return pixels


MAX_IMAGE_VALUES = 200_000_000  # pixels x channels a header may claim (a fluoroscope frame: ~10^6)


def _check_claimed_pixels(path: Path, values: int) -> None:
    if values > MAX_IMAGE_VALUES:
        raise InputError(path, f"the image header claims {values:,} pixel values (at most "
                               f"{MAX_IMAGE_VALUES:,} are read): corrupt or not a fluoroscopy image")


def _looks_truncated(path: Path, data: np.ndarray) -> bool:
    """OpenCV decodes cut-off JPEG / PNG files with a warning only: check their end markers."""
    suffix = path.suffix.lower()
    tail = data[-16:].tobytes()
    if suffix in (".jpg", ".jpeg"):
        return b"\xff\xd9" not in tail
    if suffix == ".png":
        return b"IEND" not in tail
    return False


def _has_dicom_preamble(path: Path) -> bool:
    try:
        with open(path, "rb") as handle:
            head = handle.read(132)
    except OSError:
        return False
    return len(head) == 132 and head[128:] == b"DICM"


def _read_dicom(path: Path) -> np.ndarray:
    import pydicom
    from pydicom.errors import InvalidDicomError

    try:
        dataset = pydicom.dcmread(path)
        pixels = dataset.pixel_array
    except InvalidDicomError:
        raise InputError(path, "not a valid DICOM file") from None
    except OSError as exc:
        raise InputError(path, f"cannot read the file: {describe_os_error(exc)}") from None
    except AttributeError:
        raise InputError(path, "DICOM file has no pixel data") from None
    except Exception as exc:  # pydicom raises several types on corrupt pixel data
        raise InputError(path, f"corrupt or truncated DICOM pixel data ({type(exc).__name__})") from None
    photometric = str(getattr(dataset, "PhotometricInterpretation", "MONOCHROME2")).upper()
    samples = int(getattr(dataset, "SamplesPerPixel", 1))
    if samples > 1:
        if pixels.ndim != 3:
            raise InputError(path, f"DICOM holds {pixels.shape[0]} colour frames; fluorogui needs one image")
        return _to_unit_gray(path, pixels, "rgb")
    if pixels.ndim != 2:
        raise InputError(path, f"DICOM holds {pixels.shape[0]} frames; fluorogui needs one 2D image per file")
    slope = float(getattr(dataset, "RescaleSlope", 1.0) or 1.0)
    intercept = float(getattr(dataset, "RescaleIntercept", 0.0) or 0.0)
    bits = int(getattr(dataset, "BitsStored", 8 * pixels.dtype.itemsize))
    signed = int(getattr(dataset, "PixelRepresentation", 0)) == 1
    low, high = (-(2 ** (bits - 1)), 2 ** (bits - 1) - 1) if signed else (0, 2**bits - 1)
    ends = sorted((low * slope + intercept, high * slope + intercept))
    values = pixels.astype(np.float64) * slope + intercept
    image = (values - ends[0]) / max(ends[1] - ends[0], 1e-12)
    if photometric == "MONOCHROME1":
        image = 1.0 - image
    return np.clip(image, 0.0, 1.0).astype(np.float32)


# -- conversion -----------------------------------------------------------------------------------
def _to_unit_gray(path: Path, pixels: np.ndarray, channel_order: str) -> np.ndarray:
    if pixels.ndim == 3 and pixels.shape[2] in (3, 4):
        scaled = _to_unit(path, pixels[:, :, :3])
        weights = _LUMA_RGB if channel_order == "rgb" else _LUMA_RGB[::-1]
        return (scaled @ weights).astype(np.float32)
    if pixels.ndim == 3 and pixels.shape[2] in (1, 2):
        pixels = pixels[:, :, 0]  # gray (+ alpha)
    if pixels.ndim != 2:
        raise InputError(path, f"is a {pixels.ndim}D array of shape {pixels.shape}; fluorogui needs one 2D image")
    if min(pixels.shape) == 0:
        raise InputError(path, "image has no pixels")
    return _to_unit(path, pixels).astype(np.float32)


def _to_unit(path: Path, pixels: np.ndarray) -> np.ndarray:
    if pixels.dtype == np.bool_:
        return pixels.astype(np.float64)
    if np.issubdtype(pixels.dtype, np.integer):
        info = np.iinfo(pixels.dtype)
        return np.clip(pixels.astype(np.float64) / info.max, 0.0, 1.0)
    if np.issubdtype(pixels.dtype, np.floating):
        values = pixels.astype(np.float64)
        if not np.all(np.isfinite(values)):
            raise InputError(path, "floating-point image contains NaN or infinite values")
        return np.clip(values, 0.0, 1.0)
    raise InputError(path, f"unsupported pixel type {pixels.dtype}")
