"""DICOM images: header first (size, frames, bit depth), then one frame at a time.

Pixel data are decoded by pydicom with its plug-ins for compressed transfer syntaxes
(pylibjpeg with libjpeg and openjpeg: JPEG baseline / lossless / LS, JPEG 2000; RLE is
native). Only the frame asked for is decoded (``pydicom.pixels.pixel_array(index=)``).
Rescale slope / intercept are applied and values scaled by the stored bit range, so a
12-bit run stays on one scale; MONOCHROME1 is inverted.

Where the header has DistanceSourceToDetector, DistanceSourceToPatient and
ImagerPixelSpacing, ``dicom_starting_view`` offers a view geometry to start from.
"""
from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np

from fluorogui.core.projection.geometry import GeometryError, View
from fluorogui.io.errors import InputError, describe_os_error

_PIXEL_TAGS = ("PixelData", "FloatPixelData", "DoubleFloatPixelData")


@dataclass(frozen=True)
class DicomHeader:
    width: int
    height: int
    frames: int
    bits: int
    samples: int
    transfer_syntax: str
    dataset: object  # pydicom Dataset without pixel data


def read_dicom_header(path) -> DicomHeader:
    """The header of a DICOM file, pixel data left unread; InputError when it has none."""
    import pydicom
    from pydicom.errors import InvalidDicomError

    path = Path(path)
    try:
        dataset = pydicom.dcmread(path, defer_size="64 KB")
    except InvalidDicomError:
        raise InputError(path, "not a valid DICOM file") from None
    except OSError as exc:
        raise InputError(path, f"cannot read the file: {describe_os_error(exc)}") from None
    except Exception as exc:  # pydicom raises several types on corrupt headers
        raise InputError(path, f"corrupt or truncated DICOM header ({type(exc).__name__})") from None
    if not any(tag in dataset for tag in _PIXEL_TAGS):
        raise InputError(path, "DICOM file has no pixel data (not an image)")
    try:
        width, height = int(dataset.Columns), int(dataset.Rows)
        frames = int(getattr(dataset, "NumberOfFrames", 1) or 1)
        bits = int(getattr(dataset, "BitsStored", getattr(dataset, "BitsAllocated", 8)))
        samples = int(getattr(dataset, "SamplesPerPixel", 1))
    except (AttributeError, TypeError, ValueError):
        raise InputError(path, "DICOM header lacks valid Rows / Columns") from None
    syntax = str(getattr(getattr(dataset, "file_meta", None), "TransferSyntaxUID", "") or "")
    try:
        from pydicom.uid import UID

        syntax = UID(syntax).name if syntax else "unknown"
    except Exception:
        pass
    return DicomHeader(width, height, frames, bits, samples, syntax, dataset)


def read_dicom_frame(path, index: int, header: DicomHeader | None = None) -> np.ndarray:
    """Frame ``index`` (0-based) as a 2D float32 array in [0, 1] (colour becomes luminance)."""
    from pydicom.pixels import pixel_array

    path = Path(path)
    header = header or read_dicom_header(path)
    if not 0 <= index < header.frames:
        raise InputError(path, f"the DICOM file has {header.frames} frames; frame {index} does not exist")
    try:
        pixels = pixel_array(path, index=index if header.frames > 1 else None)
    except OSError as exc:
        raise InputError(path, f"cannot read the file: {describe_os_error(exc)}") from None
    except (NotImplementedError, RuntimeError) as exc:
        raise InputError(path, f"cannot decode the pixel data ({header.transfer_syntax}): {exc}") from None
    except Exception as exc:  # pydicom raises several types on corrupt pixel data
        raise InputError(path, f"corrupt or truncated DICOM pixel data ({type(exc).__name__})") from None
    dataset = header.dataset
    if header.samples > 1:
        rgb = pixels[..., :3].astype(np.float64) / float(2 ** min(header.bits, 16) - 1)
        return np.clip(rgb @ np.array([0.299, 0.587, 0.114]), 0.0, 1.0).astype(np.float32)
    if pixels.ndim != 2:
        raise InputError(path, f"DICOM frame has shape {pixels.shape}; fluorogui needs 2D images")
    slope = float(getattr(dataset, "RescaleSlope", 1.0) or 1.0)
    intercept = float(getattr(dataset, "RescaleIntercept", 0.0) or 0.0)
    bits = header.bits
    signed = int(getattr(dataset, "PixelRepresentation", 0)) == 1
    low, high = (-(2 ** (bits - 1)), 2 ** (bits - 1) - 1) if signed else (0, 2**bits - 1)
    ends = sorted((low * slope + intercept, high * slope + intercept))
    values = pixels.astype(np.float64) * slope + intercept
    image = (values - ends[0]) / max(ends[1] - ends[0], 1e-12)
    if str(getattr(dataset, "PhotometricInterpretation", "MONOCHROME2")).upper() == "MONOCHROME1":
        image = 1.0 - image
    return np.clip(image, 0.0, 1.0).astype(np.float32)


def dicom_starting_view(path, name: str = "") -> View | None:
    """A view geometry from the header's source distances and detector pixel spacing, or None.

    World frame: origin at the isocentre (DistanceSourceToPatient from the source), source
    on +z, intensifier towards -z, image columns along +x and rows along -y, principal
    point at the image centre. A start for the user to refine, not a calibration.
    """
    header = read_dicom_header(path)
    ds = header.dataset
    try:
        sid = float(ds.DistanceSourceToDetector)
        sod = float(ds.DistanceSourceToPatient)
        row_spacing, col_spacing = (float(v) for v in ds.ImagerPixelSpacing)
    except (AttributeError, TypeError, ValueError):
        return None
    try:
        view = View.looking_at(
            source=(0.0, 0.0, sod), target=(0.0, 0.0, 0.0), up=(0.0, 1.0, 0.0), distance=sid,
            image_size=(header.width, header.height), pitch=col_spacing, name=name or Path(path).stem,
        )
        view = View(view.source, view.normal, view.e_u, view.e_v, view.distance, (col_spacing, row_spacing),
                    view.principal_point, view.image_size, view.name)
    except GeometryError:
        return None
    view.extra.update(source_format="DICOM header", starting_geometry=True)
    return view
