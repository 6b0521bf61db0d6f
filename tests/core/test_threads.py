"""Per-view work side by side (``core.threads.each_view``): the plain loop's results in its
order, its first error, nothing left running after a call, no helper waiting on helpers,
and a match that comes out the same to the last bit with threads or without."""
import json
import os
import subprocess
import sys
import threading
import time

import numpy as np
import pytest

from fluorogui.core import threads
from fluorogui.core.threads import each_view, set_threads


@pytest.fixture(autouse=True)
def two_threads():
    set_threads(2)
    yield
    set_threads(2)


def test_results_come_in_order_and_the_views_run_side_by_side():
    names = {}

    def work(k):
        names[k] = threading.current_thread().name
        time.sleep(0.05 * (2 - k))  # the first view is the slow one
        return k * 10

    assert each_view(work, [0, 1]) == [0, 10]
    assert names[0] == threading.current_thread().name and threads.is_view_thread_name(names[1])


def test_the_first_views_error_is_raised_and_the_other_view_has_finished():
    done = []

    def work(k):
        if k == 0:
            raise ValueError("view 1: no outline")
        time.sleep(0.05)
        done.append(k)

    with pytest.raises(ValueError, match="view 1"):
        each_view(work, [0, 1])
    assert done == [1]  # waited for before the error came out
    with pytest.raises(KeyError):
        each_view(lambda k: {}[k], [5, 0])


def test_a_helper_runs_nested_work_itself():
    assert each_view(lambda k: each_view(lambda j: j + k, [0, 1]), [0, 10]) == [[0, 1], [10, 11]]


def test_one_thread_runs_on_the_callers_thread():
    set_threads(1)
    names = each_view(lambda k: threading.current_thread().name, [0, 1])
    assert names == [threading.current_thread().name] * 2


def test_a_match_is_the_same_with_threads_or_without():
    from fluorogui.core.matching.loop import LoopSettings, segment_and_match
    from fluorogui.core.projection.mesh import prepare_mesh
    from fluorogui.core.projection.pose import transform_points
    from fluorogui.simulation.phantoms import femoral_component_mesh
    from fluorogui.simulation.protocols import dual_orthogonal_views
    from fluorogui.simulation.render import render_fluoro

    truth = np.array([2.0, 3.0, -4.0, 10.0, 20.0, -30.0])
    mesh = prepare_mesh(*femoral_component_mesh())
    views = dual_orthogonal_views()
    world = transform_points(truth, mesh.vertices)
    images = [render_fluoro(v, [(world, mesh.faces)], np.random.default_rng(3)) for v in views]
    start = truth + np.array([0.6, -0.5, 0.4, 2.0, -1.5, 1.0])
    poses = []
    for n in (1, 2):
        set_threads(n)
        poses.append(segment_and_match(images, views, mesh, start, loop=LoopSettings(rim="off")).pose)
    np.testing.assert_array_equal(poses[0], poses[1])


def test_the_environment_can_turn_the_threads_off():
    code = "import fluorogui.core.threads as t; print(t._threads)"
    default = str(min(2, os.cpu_count() or 1))
    for value, expected in (("1", "1"), ("3", "3"), ("many", default)):  # (not a number: the default)
        env = dict(os.environ, FLUOROGUI_VIEW_THREADS=value)
        out = subprocess.run([sys.executable, "-c", code], env=env, capture_output=True, text=True, check=True)
        assert out.stdout.strip() == expected


_BLAS_THREADS = """
import ctypes, json
import numpy, scipy.linalg
from fluorogui.core import threads
def counts():
    out = []
    for path in threads._blas_libraries():
        lib = ctypes.CDLL(path)
        for name in ("scipy_openblas_get_num_threads64_", "scipy_openblas_get_num_threads",
                     "openblas_get_num_threads64_", "openblas_get_num_threads"):
            if hasattr(lib, name):
                out.append(getattr(lib, name)())
                break
    return out
before = counts()
threads.single_threaded_blas()
print(json.dumps([before, counts()]))
"""


def test_blas_runs_on_one_thread_after_the_matcher_starts():
    """OpenBLAS's own threads spin beside the view threads (10x the CPU per rim-fit
    product): ``single_threaded_blas`` sets each loaded OpenBLAS to one thread, or to
    ``FLUOROGUI_BLAS_THREADS``."""
    env = {**os.environ, "OPENBLAS_NUM_THREADS": "2", "PYTHONPATH": os.getcwd()}
    done = subprocess.run([sys.executable, "-c", _BLAS_THREADS], capture_output=True, text=True, env=env, timeout=60)
    before, after = json.loads(done.stdout)
    if not before:
        pytest.skip("no OpenBLAS loaded (another BLAS is left as it is)")
    assert before == [2] * len(before) and after == [1] * len(after)
    env["FLUOROGUI_BLAS_THREADS"] = "2"
    done = subprocess.run([sys.executable, "-c", _BLAS_THREADS], capture_output=True, text=True, env=env, timeout=60)
    after = json.loads(done.stdout)[1]  # (with OpenCV's own OpenBLAS, loaded with it)
    assert len(after) >= len(before) and after == [2] * len(after)


def test_products_are_the_same_with_one_blas_thread_or_more():
    """BLAS splits a product's rows and columns among its threads, not its sums: the rim
    fit's templates come out the same to the last bit."""
    code = ("import numpy as np, sys\nfrom fluorogui.core.outlines import rim\nfrom fluorogui.core import threads\n"
            "L = np.cumsum(np.random.default_rng(0).random((300, len(rim._L_OFFSETS))), axis=1)\n"
            "if sys.argv[1] == '1': threads.single_threaded_blas()\n"
            "T = [rim._templates(L, mu, s) for mu in rim.MU_GRID[::3] for s in rim.SIGMA_GRID[::4]]\n"
            "sys.stdout.write(np.concatenate(T).tobytes().hex())")
    env = {**os.environ, "OPENBLAS_NUM_THREADS": "2", "PYTHONPATH": os.getcwd()}
    outs = [subprocess.run([sys.executable, "-c", code, n], capture_output=True, text=True, env=env, timeout=60).stdout
            for n in ("1", "2")]
    assert outs[0] and outs[0] == outs[1]


def test_opencv_runs_on_one_thread_after_the_matcher_starts():
    """OpenCV's own thread pool, like BLAS's, only spins beside the view threads (a fifth
    more CPU per segmentation): one thread once the matcher starts, or
    ``FLUOROGUI_OPENCV_THREADS``."""
    code = ("import cv2, json\ncv2.setNumThreads(2)\nfrom fluorogui.core import threads\nbefore = cv2.getNumThreads()\n"
            "threads.single_threaded_blas()\nprint(json.dumps([before, cv2.getNumThreads()]))")
    env = {**os.environ, "PYTHONPATH": os.getcwd()}
    done = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, env=env, timeout=60)
    assert json.loads(done.stdout) == [2, 1]
    env["FLUOROGUI_OPENCV_THREADS"] = "2"
    done = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, env=env, timeout=60)
    assert json.loads(done.stdout) == [2, 2]
