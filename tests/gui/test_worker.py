"""The worker: progress then a result on the GUI thread; a cancel gives only a cancel message."""
import threading
import time

import pytest

pytest.importorskip("pytestqt")

from fluorogui.gui.worker import TaskRunner  # noqa: E402


def record(runner):
    seen = []
    for name in ("progress", "item", "finished", "cancelled", "failed"):
        getattr(runner, name).connect(lambda *args, n=name: seen.append((n, args)))
    return seen


def test_progress_items_then_result_in_order(qtbot):
    runner = TaskRunner(interval=0.0)
    seen = record(runner)
    main_thread = threading.get_ident()
    threads = []
    runner.progress.connect(lambda _p: threads.append(threading.get_ident()))

    def task(reporter):
        for i in range(4):
            reporter.report(i)
            reporter.emit(f"item {i}")
        return "done"

    with qtbot.waitSignal(runner.finished, timeout=10000):
        assert runner.start(task, "test")
    names = [n for n, _ in seen]
    assert names[-1] == "finished" and seen[-1][1] == ("done",)
    assert [a[0] for n, a in seen if n == "progress"] == [0, 1, 2, 3]
    assert [a[0] for n, a in seen if n == "item"] == [f"item {i}" for i in range(4)]
    assert set(threads) == {main_thread}  # delivered on the GUI thread
    assert not runner.is_running()


def test_throttling_forwards_only_some_reports_but_every_item(qtbot):
    runner = TaskRunner(interval=3600.0)
    seen = record(runner)

    def task(reporter):
        for i in range(100):
            reporter.report(i)
            reporter.emit(i)
        return None

    with qtbot.waitSignal(runner.finished, timeout=10000):
        runner.start(task)
    assert [a[0] for n, a in seen if n == "progress"] == [0]
    assert len([n for n, _ in seen if n == "item"]) == 100


def test_cancel_gives_only_a_cancel_message(qtbot):
    runner = TaskRunner(interval=0.0)
    seen = record(runner)
    started = threading.Event()

    def task(reporter):
        started.set()
        while not reporter.cancelled():
            time.sleep(0.001)
        return "should not arrive"

    runner.start(task)
    assert started.wait(10)
    with qtbot.waitSignal(runner.cancelled, timeout=10000):
        runner.cancel()
    assert [n for n, _ in seen] == ["cancelled"]


def test_an_exception_becomes_a_failure_message(qtbot):
    runner = TaskRunner()
    seen = record(runner)

    def task(reporter):
        raise ValueError("outline has 2 points")

    with qtbot.waitSignal(runner.failed, timeout=10000) as blocker:
        runner.start(task)
    assert blocker.args[0] == "Outline has 2 points."  # a sentence, no class name
    assert [n for n, _ in seen] == ["failed"]
    assert runner.start(lambda r: 1)  # usable again
    with qtbot.waitSignal(runner.finished, timeout=10000):
        pass


def test_error_messages_never_name_a_class():
    from fluorogui.core.outlines.spline import OutlineError
    from fluorogui.gui.worker import describe_error
    from fluorogui.io.errors import InputError

    assert describe_error(OutlineError("outline crosses itself at point 5")) == "Outline crosses itself at point 5."
    assert describe_error(InputError("a.tif", "not an image")) == "a.tif: not an image"
    text = describe_error(ImportError("cannot import name 'find_components'", name="fluorogui.core.search.find"))
    assert "ImportError" not in text and "not available" in text


def test_only_one_task_at_a_time(qtbot):
    runner = TaskRunner()
    gate = threading.Event()
    runner.start(lambda r: gate.wait(10))
    assert not runner.start(lambda r: 2)
    with qtbot.waitSignal(runner.finished, timeout=10000):
        gate.set()
