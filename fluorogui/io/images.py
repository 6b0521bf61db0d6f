"""Read fluoroscopic images and videos as 2D grayscale float32 arrays in [0, 1]; write images.

Formats: TIFF (8/16-bit, uncompressed, LZW, Deflate, PackBits, JPEG through imagecodecs;
stacks), PNG, JPEG, BMP, DICOM (single- and multi-frame, compressed transfer syntaxes:
``fluorogui.io.dicom``), AVI / MP4 (lazily, frame by frame: ``fluorogui.io.video``). One
frame of a multi-frame file is named ``FILE@N`` (0-based). Every reader checks the size
in the header against ``MAX_IMAGE_SIDE_PX`` / ``MAX_IMAGE_PIXELS`` before decoding.
16-bit images keep their full depth (float32 holds every 16-bit level); the display
windows them (``fluorogui.gui.panels.image_panel``).

Integer images are scaled by their type's full range (8-bit / 255, 16-bit / 65535), so a
sequence keeps one intensity scale from frame to frame. DICOM pixel data get their rescale
slope / intercept and are scaled by the stored bit range; MONOCHROME1 is inverted so bone
and metal look the same as in the other formats. Colour images become luminance.

A damaged JPEG is refused, not decoded into a picture with a grey band: libjpeg fills what
a cut-off or corrupt scan lacks and only prints a warning (``Premature end of JPEG file``,
``Corrupt JPEG data: ...``) on the process's stderr, which the reader captures while it
decodes (POSIX). An image read for matching must show something: ``check_not_blank``
refuses one value everywhere (an all-0 or all-255 frame), never a dark or flat real one.
"""
from __future__ import annotations

import os
import re
import tempfile
import threading
from contextlib import contextmanager
from dataclasses import dataclass
from pathlib import Path

import cv2
import numpy as np

from fluorogui.io.errors import InputError, describe_os_error
from fluorogui.io.files import check_input_file

TIFF_SUFFIXES = (".tif", ".tiff")
CV2_SUFFIXES = (".png", ".jpg", ".jpeg", ".bmp")
DICOM_SUFFIXES = (".dcm", ".dicom")
VIDEO_SUFFIXES = (".avi", ".mp4", ".mov", ".mkv")
IMAGE_SUFFIXES = TIFF_SUFFIXES + CV2_SUFFIXES + DICOM_SUFFIXES

_LUMA_RGB = np.array([0.299, 0.587, 0.114])


# -- limits and frame references -----------------------------------------------------------
#: Largest image side accepted, checked in the file's header before anything is decoded.
MAX_IMAGE_SIDE_PX = 16384
#: Largest image accepted (pixels): 64 Mpx, i.e. 256 MiB as float32.
MAX_IMAGE_PIXELS = 8192 * 8192
_FRAME_REFERENCE = re.compile(r"^(?P<file>.+)@(?P<index>\d+)$")


@dataclass(frozen=True)
class ImageInfo:
    """What a file's header says: format, size (px), frame count, bits per sample."""

    format: str
    width: int
    height: int
    frames: int
    bits: int
    detail: str = ""  # compression, transfer syntax or codec

    def describe(self) -> str:
        frames = f", {self.frames} frames" if self.frames != 1 else ""
        detail = f", {self.detail}" if self.detail else ""
        return f"{self.format} {self.width}x{self.height}, {self.bits}-bit{frames}{detail}"


def frame_reference(path, index: int) -> Path:
    """The path naming frame ``index`` (0-based) of a multi-frame file or video: ``FILE@N``."""
    return Path(f"{path}@{int(index)}")


def split_frame_reference(path) -> tuple[Path, int | None]:
    """``FILE@N`` to (FILE, N); an existing file (even with '@' in its name) to (path, None)."""
    path = Path(path)
    match = _FRAME_REFERENCE.match(str(path))
    if match is None or path.exists():
        return path, None
    return Path(match.group("file")), int(match.group("index"))


def is_multi_frame(path) -> bool:
    """True for videos and for DICOM / TIFF files holding more than one frame."""
    return image_info(path).frames > 1 or Path(path).suffix.lower() in VIDEO_SUFFIXES


# -- reading ------------------------------------------------------------------------------------
def read_image(path) -> np.ndarray:
    """One image as a 2D float32 array in [0, 1] (rows, columns).

    ``path`` is an image file, or ``FILE@N`` for frame N (0-based) of a multi-frame DICOM,
    a TIFF stack or a video. The header's size is checked before any decoding.
    """
    path, index = split_frame_reference(path)
    _check_file(path)
    if index is not None:
        return read_frame(path, index)
    info = image_info(path)
    if info.frames > 1:
        kind = "stack of" if info.format == "TIFF" else "DICOM holds" if info.format == "DICOM" else "video of"
        raise InputError(path, f"{kind} {info.frames} frames; give one frame as {path.name}@N (0-based) "
                               "or the whole file as an image sequence")
    return read_frame(path, 0)


def read_frame(path, index: int) -> np.ndarray:
    """Frame ``index`` (0-based) of any supported file (a single image has only frame 0)."""
    path = Path(path)
    _check_file(path)
    index = int(index)
    if index < 0:
        raise InputError(path, f"frame index {index} is negative")
    suffix = path.suffix.lower()
    if suffix in VIDEO_SUFFIXES:
        from fluorogui.io.video import read_video_frame_raw, video_info

        _check_size(path, *_video_size(video_info(path)))
        return _to_unit_gray(path, read_video_frame_raw(path, index), "bgr")
    if suffix in DICOM_SUFFIXES or (suffix not in TIFF_SUFFIXES + CV2_SUFFIXES and has_dicom_preamble(path)):
        from fluorogui.io.dicom import read_dicom_frame, read_dicom_header

        header = read_dicom_header(path)
        _check_size(path, header.width, header.height)
        return read_dicom_frame(path, index, header)
    if suffix in TIFF_SUFFIXES:
        return _to_unit_gray(path, _read_tiff(path, index), "rgb")
    if suffix in CV2_SUFFIXES:
        if index != 0:
            raise InputError(path, f"is a single image; frame {index} does not exist")
        _check_size(path, *_pillow_size(path))
        return _to_unit_gray(path, _read_cv2(path), "bgr")
    raise InputError(
        path, f"unsupported image type '{suffix or '(none)'}' (use TIFF, PNG, JPEG, BMP, DICOM, AVI or MP4)"
    )


def image_info(path) -> ImageInfo:
    """Format, size, frame count and bit depth from the header alone (no pixel decoding)."""
    path, index = split_frame_reference(path)
    _check_file(path)
    suffix = path.suffix.lower()
    if suffix in VIDEO_SUFFIXES:
        from fluorogui.io.video import video_info

        v = video_info(path)
        return ImageInfo(suffix.lstrip(".").upper(), v.width, v.height, v.frames, 8, f"codec {v.codec}")
    if suffix in DICOM_SUFFIXES or (suffix not in TIFF_SUFFIXES + CV2_SUFFIXES and has_dicom_preamble(path)):
        from fluorogui.io.dicom import read_dicom_header

        h = read_dicom_header(path)
        return ImageInfo("DICOM", h.width, h.height, h.frames, h.bits, h.transfer_syntax)
    if suffix in TIFF_SUFFIXES:
        return _tiff_info(path)
    if suffix in CV2_SUFFIXES:
        width, height, bits, _ = _pillow_header(path)
        return ImageInfo(suffix.lstrip(".").upper().replace("JPG", "JPEG"), width, height, 1, bits)
    raise InputError(path, f"unsupported image type '{suffix or '(none)'}' "
                           "(use TIFF, PNG, JPEG, BMP, DICOM, AVI or MP4)")


def frame_count(path) -> int:
    """Frames in a file: 1 for a single image, N for a multi-frame DICOM, TIFF stack or video."""
    return image_info(path).frames


def read_video_frames(path, indices=None) -> list[np.ndarray]:
    """Frames of an AVI / MP4 video as 2D float32 arrays in [0, 1], read lazily one by one.

    ``indices`` selects frames (0-based); None reads them all. An index past the end of the
    video raises InputError.
    """
    path = Path(path)
    _check_file(path)
    if path.suffix.lower() not in VIDEO_SUFFIXES:
        raise InputError(path, f"unsupported video type '{path.suffix or '(none)'}' (use AVI or MP4)")
    if indices is None:
        from fluorogui.io.video import video_info

        indices = range(video_info(path).frames)
    return [read_frame(path, i) for i in indices]


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


def write_rgb_png(path, rgb) -> None:
    """Write an (H, W, 3) uint8 RGB picture as PNG (residual maps, overlays)."""
    path = Path(path)
    pixels = np.asarray(rgb)
    if pixels.ndim != 3 or pixels.shape[2] != 3 or pixels.dtype != np.uint8:
        raise InputError(path, f"can only write RGB uint8 pictures, got {pixels.shape} {pixels.dtype}")
    ok, data = cv2.imencode(".png", np.ascontiguousarray(pixels[..., ::-1]))
    if not ok:
        raise InputError(path, "could not encode the PNG picture")
    try:
        tmp = path.with_name(f".{path.name}.tmp")
        tmp.write_bytes(data.tobytes())
        tmp.replace(path)
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


def _tiff_info(path: Path) -> ImageInfo:
    import tifffile

    try:
        with tifffile.TiffFile(path) as tif:
            page = tif.pages[0]
            frames = len(tif.pages)
            if frames == 1 and page.ndim == 3 and page.samplesperpixel == 1:
                frames = page.shape[0]  # a volume stored in one page
            return ImageInfo("TIFF", int(page.imagewidth), int(page.imagelength), frames,
                             int(page.bitspersample), _compression_name(page.compression))
    except OSError as exc:
        raise InputError(path, f"cannot read the file: {describe_os_error(exc)}") from None
    except Exception as exc:  # tifffile raises several types on corrupt data
        raise InputError(path, f"corrupt or truncated TIFF ({type(exc).__name__})") from None


def _compression_name(code) -> str:
    import tifffile

    try:
        return tifffile.COMPRESSION(int(code)).name.lower()
    except ValueError:
        return f"compression {int(code)}"


def _read_tiff(path: Path, index: int = 0) -> np.ndarray:
    import tifffile

    info = _tiff_info(path)
    _check_size(path, info.width, info.height)
    if index >= info.frames:
        raise InputError(path, f"the TIFF has {info.frames} frames; frame {index} does not exist")
    try:
        with tifffile.TiffFile(path) as tif:
            if len(tif.pages) == 1 and info.frames > 1:
                _check_claimed_pixels(path, int(np.prod(tif.pages[0].shape, dtype=np.float64)))  # before allocating
                return tif.pages[0].asarray()[index]
            page = tif.pages[index]
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
        raise InputError(path, f"corrupt or truncated TIFF ({type(exc).__name__}: {exc})") from None


def _pillow_header(path: Path) -> tuple[int, int, int, str]:
    """Width, height, bits and mode of a PNG / JPEG / BMP from its header (Pillow opens lazily)."""
    import warnings

    from PIL import Image

    try:
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", Image.DecompressionBombWarning)
            with Image.open(path) as im:
                width, height, mode = im.size[0], im.size[1], im.mode
    except Image.DecompressionBombError:
        raise InputError(path, f"image header claims a size over the limit of {_limit_text()}; "
                               "refused before decoding") from None
    except Exception:
        raise InputError(path, f"corrupt or unreadable {path.suffix.lstrip('.').upper()} image") from None
    bits = 16 if mode.startswith("I;16") or mode == "I" else 8
    return width, height, bits, mode


def _pillow_size(path: Path) -> tuple[int, int]:
    width, height, _, _ = _pillow_header(path)
    return width, height


def _video_size(info) -> tuple[int, int]:
    return info.width, info.height


def _limit_text() -> str:
    return f"{MAX_IMAGE_SIDE_PX} px a side or {MAX_IMAGE_PIXELS:,} pixels"


def _check_size(path: Path, width: int, height: int) -> None:
    """Refuse absurd sizes from the header, before a decoder allocates them."""
    if width <= 0 or height <= 0:
        raise InputError(path, f"image header gives an empty size {width}x{height}")
    if max(width, height) > MAX_IMAGE_SIDE_PX or width * height > MAX_IMAGE_PIXELS:
        raise InputError(path, f"image header claims {width}x{height} px, over the limit of {_limit_text()}; "
                               "refused before decoding")


def _read_cv2(path: Path) -> np.ndarray:
    try:
        data = np.fromfile(path, dtype=np.uint8)  # works with non-ASCII paths, unlike cv2.imread
    except OSError as exc:
        raise InputError(path, f"cannot read the file: {describe_os_error(exc)}") from None
    if data[:8].tobytes() == b"\x89PNG\r\n\x1a\n" and data.size >= 24:
        _check_claimed_pixels(path, int.from_bytes(data[16:20].tobytes(), "big") *
                              int.from_bytes(data[20:24].tobytes(), "big"))  # IHDR, before decoding
    jpeg = path.suffix.lower() in (".jpg", ".jpeg")
    with _native_messages(jpeg) as messages:
        pixels = cv2.imdecode(data, cv2.IMREAD_UNCHANGED)
    if pixels is None:
        raise InputError(path, f"corrupt or unreadable {path.suffix.lstrip('.').upper()} image")
    if _looks_truncated(path, data):
        raise InputError(path, f"truncated {path.suffix.lstrip('.').upper()} image")
    damage = next((line.strip() for line in messages if _is_jpeg_damage(line)), None)
    if damage:
        raise InputError(path, f"damaged JPEG image: the decoder reports {damage[:80]!r} (a truncated or "
                               "corrupt file: part of the picture is missing)")
    return pixels


#: libjpeg's "N extraneous bytes before marker": a few are some encoders' padding; more are
#: scan data the decoder did not use (overwritten bytes it decoded as other codes)
MAX_EXTRANEOUS_BYTES = 16
_EXTRANEOUS = re.compile(r"(\d+) extraneous bytes")


def _is_jpeg_damage(line: str) -> bool:
    """A libjpeg warning that data of the picture is missing or wrong (not a harmless one:
    a bad ICC profile, a few extraneous bytes before a marker)."""
    line = line.strip()
    if line.startswith("Corrupt JPEG data:"):
        extraneous = _EXTRANEOUS.search(line)
        if extraneous:
            return int(extraneous.group(1)) > MAX_EXTRANEOUS_BYTES
        return "ICC" not in line
    return line.startswith(("Premature end of JPEG file", "Inconsistent progression sequence"))


_NATIVE_STDERR = threading.Lock()


@contextmanager
def _native_messages(enabled: bool = True):
    """The lines C code writes to the process's stderr (fd 2) while the block runs, in a list
    filled on the way out; the text goes on to where fd 2 pointed. One block at a time (fd 2
    is the process's); an empty list where fd 2 cannot be captured."""
    lines: list[str] = []
    if not enabled or os.name != "posix":
        yield lines
        return
    with _NATIVE_STDERR, tempfile.TemporaryFile() as sink:
        saved = -1
        try:
            saved = os.dup(2)
            os.dup2(sink.fileno(), 2)
        except OSError:  # no stderr to capture: decode without
            if saved >= 0:
                os.close(saved)
            yield lines
            return
        try:
            yield lines
        finally:
            os.dup2(saved, 2)
            os.close(saved)
            sink.seek(0)
            text = sink.read()
            if text:
                os.write(2, text)
                lines += text.decode("utf-8", "replace").splitlines()


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


def check_not_blank(image: np.ndarray, path) -> None:
    """Refuse an image read for matching that holds one value everywhere (InputError naming
    ``path``): an all-black or all-white frame shows no component. A dark or low-contrast
    frame is not blank: one pixel different is enough."""
    image = np.asarray(image)
    if image.size == 0 or float(image.min()) != float(image.max()):
        return
    value = float(image.flat[0])
    try:
        bits = image_info(path).bits
    except InputError:
        bits = 0
    top = 2 ** bits - 1 if bits in (8, 16) else 0
    shown = f"{round(value * top)}" + (f" of {top}" if value > 0 else "") if top else f"{value:.4g} of 1"
    raise InputError(path, f"the image is blank (every pixel {shown}): it shows nothing to match")


def has_dicom_preamble(path: Path) -> bool:
    """True when the file starts with DICOM's 128-byte preamble and ``DICM``."""
    try:
        with open(path, "rb") as handle:
            head = handle.read(132)
    except OSError:
        return False
    return len(head) == 132 and head[128:] == b"DICM"


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
