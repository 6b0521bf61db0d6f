"""Lazy, frame-by-frame reading of AVI / MP4 videos through OpenCV (nothing extracted to disk).

A small pool of open decoders (``MAX_OPEN_VIDEOS``) is kept so stepping through a
sequence reads each frame once, in order, without reopening the file or seeking; a jump
backwards or far forwards seeks. Frames are returned like ``read_image``'s: 2D float32 in
[0, 1]. The pool is shared by threads, each decoder behind its own lock.
"""
from __future__ import annotations

import threading
from collections import OrderedDict
from dataclasses import dataclass
from pathlib import Path

import cv2
import numpy as np

from fluorogui.io.errors import InputError

#: Open decoders kept at once (two cameras, plus a preview, plus one spare).
MAX_OPEN_VIDEOS = 4
#: A forward jump up to this many frames decodes through instead of seeking.
_SKIP_LIMIT = 32


@dataclass(frozen=True)
class VideoInfo:
    width: int
    height: int
    frames: int
    fps: float
    codec: str


class _OpenVideo:
    def __init__(self, path: Path):
        self.path = path
        self.capture = cv2.VideoCapture(str(path))
        self.next_index = 0
        self.lock = threading.Lock()

    def release(self) -> None:
        with self.lock:
            self.capture.release()


_pool: OrderedDict[tuple, _OpenVideo] = OrderedDict()
_pool_lock = threading.Lock()


def _key(path: Path) -> tuple:
    stat = path.stat()
    return str(path), stat.st_mtime_ns, stat.st_size


def _open(path: Path) -> _OpenVideo:
    key = _key(path)
    with _pool_lock:
        video = _pool.get(key)
        if video is not None:
            _pool.move_to_end(key)
            return video
    video = _OpenVideo(path)
    if not video.capture.isOpened():
        video.release()
        raise InputError(path, "cannot open the video (corrupt file or a codec OpenCV cannot read)")
    with _pool_lock:
        _pool[key] = video
        while len(_pool) > MAX_OPEN_VIDEOS:
            _, old = _pool.popitem(last=False)
            old.release()
    return video


def close_videos() -> None:
    """Release every open decoder (tests, and before a file is replaced)."""
    with _pool_lock:
        videos = list(_pool.values())
        _pool.clear()
    for video in videos:
        video.release()


def _codec(capture) -> str:
    code = int(capture.get(cv2.CAP_PROP_FOURCC))
    text = "".join(chr((code >> (8 * k)) & 0xFF) for k in range(4))
    return text if text.isprintable() and text.strip() else "unknown"


def video_info(path) -> VideoInfo:
    """Size, frame count, frame rate and codec from the container, without decoding a frame."""
    path = Path(path)
    video = _open(path)
    with video.lock:
        capture = video.capture
        info = VideoInfo(
            width=int(capture.get(cv2.CAP_PROP_FRAME_WIDTH)),
            height=int(capture.get(cv2.CAP_PROP_FRAME_HEIGHT)),
            frames=int(capture.get(cv2.CAP_PROP_FRAME_COUNT)),
            fps=float(capture.get(cv2.CAP_PROP_FPS) or 0.0),
            codec=_codec(capture),
        )
    if info.width <= 0 or info.height <= 0 or info.frames <= 0:
        raise InputError(path, f"the video has no readable frames (codec '{info.codec}')")
    return info


def read_video_frame_raw(path, index: int) -> np.ndarray:
    """Frame ``index`` (0-based) as OpenCV decodes it (BGR uint8, usually)."""
    path = Path(path)
    index = int(index)
    if index < 0:
        raise InputError(path, f"frame index {index} is negative")
    video = _open(path)
    with video.lock:
        capture = video.capture
        gap = index - video.next_index
        if gap < 0 or gap > _SKIP_LIMIT:
            capture.set(cv2.CAP_PROP_POS_FRAMES, index)
        else:
            for _ in range(gap):
                if not capture.grab():
                    break
        ok, frame = capture.read()
        video.next_index = index + 1 if ok else 0
        if not ok:
            capture.set(cv2.CAP_PROP_POS_FRAMES, 0)
    if not ok or frame is None:
        count = int(capture.get(cv2.CAP_PROP_FRAME_COUNT))
        if index == 0 or count <= 0:
            raise InputError(path, f"cannot decode the video's frames (codec '{_codec(capture)}' is not "
                                   "readable by OpenCV here; convert it to MJPG AVI or H.264 MP4)")
        raise InputError(path, f"the video has {count} frames; frame {index} does not exist or cannot be decoded")
    return frame
