"""Developer benchmark: peak memory and time stepping through a 2 x N-frame video session.

Writes two N-frame MJPG AVI videos (default 1000 frames of 1024x1024, a moving dark disc
on a gradient) in a temporary folder, imports them as a biplane session (frames are lazy
``FILE@N`` references: nothing is extracted), opens it in the workflow ``Session`` and
reads every frame of both cameras in order (as the app's frame slider and tracking do),
then jumps to 50 random frames. Prints the peak resident memory (``ru_maxrss``) before
and after stepping, the bound of the session's frame cache
(``IMAGE_CACHE_FRAMES`` x views x image bytes) and of the open-decoder pool
(``MAX_OPEN_VIDEOS``), and the milliseconds per frame.

Usage: .venv/bin/python benchmarks/bench_frames.py [--frames 1000] [--size 1024] [--keep DIR]
"""
from __future__ import annotations

import argparse
import resource
import shutil
import sys
import tempfile
import time
from pathlib import Path

import cv2
import numpy as np

from fluorogui.core.projection.geometry import View
from fluorogui.io.calibration import save_view_json
from fluorogui.io.importer import import_session
from fluorogui.io.video import MAX_OPEN_VIDEOS
from fluorogui.workflow.session import IMAGE_CACHE_FRAMES, Session


def peak_mib() -> float:
    return resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024.0  # Linux reports KiB


def write_video(path: Path, frames: int, size: int, phase: float) -> None:
    writer = cv2.VideoWriter(str(path), cv2.VideoWriter_fourcc(*"MJPG"), 30, (size, size), isColor=False)
    if not writer.isOpened():
        raise SystemExit("OpenCV cannot write MJPG AVI here")
    base = np.tile(np.linspace(60, 200, size, dtype=np.float32), (size, 1))
    for k in range(frames):
        frame = base.copy()
        centre = (int(size / 2 + size / 4 * np.cos(k / 40 + phase)), int(size / 2 + size / 4 * np.sin(k / 40)))
        cv2.circle(frame, centre, size // 12, 30, -1)
        writer.write(frame.astype(np.uint8))
    writer.release()


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--frames", type=int, default=1000)
    parser.add_argument("--size", type=int, default=1024)
    parser.add_argument("--keep", type=Path, help="write the videos here and keep them")
    args = parser.parse_args(argv)
    folder = args.keep or Path(tempfile.mkdtemp(prefix="bench-frames-"))
    folder.mkdir(parents=True, exist_ok=True)
    try:
        t = time.perf_counter()
        videos, cameras = [], []
        for k in range(2):
            videos.append(folder / f"cam{k + 1}.avi")
            if not videos[-1].exists():
                write_video(videos[-1], args.frames, args.size, phase=k)
            view = View.looking_at((-1000.0 if k == 0 else 0.0, 0.0 if k == 0 else -1000.0, 0.0), (0, 0, 0),
                                   (0, 0, 1), 1200.0, image_size=(args.size, args.size), pitch=0.3)
            cameras.append(folder / f"cam{k + 1}.json")
            save_view_json(view, cameras[-1])
        print(f"videos ready in {time.perf_counter() - t:.1f} s: "
              + ", ".join(f"{v.name} {v.stat().st_size / 2**20:.0f} MiB" for v in videos))
        before = peak_mib()
        t = time.perf_counter()
        session = Session(import_session(cameras, videos, {}))
        print(f"import: {time.perf_counter() - t:.2f} s, {len(session.frames)} frames per camera, "
              f"files in the folder afterwards: {sorted(p.name for p in folder.iterdir())}")
        t = time.perf_counter()
        for frame in session.frames:
            session.images(frame)
        sequential = (time.perf_counter() - t) / len(session.frames) * 1000
        rng = np.random.default_rng(0)
        t = time.perf_counter()
        jumps = rng.choice(session.frames, 50)
        for frame in jumps:
            session.images(int(frame))
        random_ms = (time.perf_counter() - t) / len(jumps) * 1000
        image_mib = args.size * args.size * 4 / 2**20
        print(f"stepping: {sequential:.1f} ms per frame pair in order, {random_ms:.1f} ms per random jump")
        print(f"frame cache bound: {IMAGE_CACHE_FRAMES} frames x 2 views x {image_mib:.0f} MiB = "
              f"{IMAGE_CACHE_FRAMES * 2 * image_mib:.0f} MiB; open decoders at most {MAX_OPEN_VIDEOS}")
        print(f"peak RSS: {before:.0f} MiB before stepping, {peak_mib():.0f} MiB after "
              f"(all frames as float32 would need {2 * args.frames * image_mib / 1024:.1f} GiB)")
    finally:
        if args.keep is None:
            shutil.rmtree(folder, ignore_errors=True)
    return 0


if __name__ == "__main__":
    sys.exit(main())
