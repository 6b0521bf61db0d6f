"""The project lock (``fluorogui.io.project.lock``): the holder named, re-entrant within a
process, stale notes taken over, live ones (and other hosts') respected, and the two races
the operating-system lock closes - a note still being written, and several processes
taking over one stale lock at once - with real processes."""
from __future__ import annotations

import json
import os
import socket
import subprocess
import sys
import textwrap

import pytest

from fluorogui.io.errors import InputError
from fluorogui.io.project.lock import ProjectLock, ProjectLocked, guard_path, lock_path, read_holder

# A process that takes the lock when told to ("go" on stdin), says how it went ("won" or
# "lost <message>") and, if it won, holds it until the next line (or until it is killed).
# With "slow-note" it pauses after taking the lock with half its note written; with
# "slow-read" every reading of the note takes 0.2 s longer.
CHILD = textwrap.dedent("""
    import sys
    import time
    from fluorogui.io.project import lock

    path, program, mode = sys.argv[1:4]
    if mode == "slow-note":
        write = lock.ProjectLock._write_note

        def slow(self):
            self.path.write_text('{"program": "' + program[:4], encoding="utf-8")  # half a note
            print("writing", flush=True)
            sys.stdin.readline()
            write(self)

        lock.ProjectLock._write_note = slow
    elif mode == "slow-read":  # widen the window between reading a note and acting on it
        read = lock.read_holder

        def slow_read(project_path):
            note = read(project_path)
            time.sleep(0.2)
            return note

        lock.read_holder = slow_read
    print("ready", flush=True)
    sys.stdin.readline()
    try:
        held = lock.ProjectLock(path, program).acquire()
    except lock.ProjectLocked as exc:
        print("lost", exc, flush=True)
        sys.exit(0)
    print("won", flush=True)
    sys.stdin.readline()
    held.release()
""")


def _child(path, program, mode="plain"):
    proc = subprocess.Popen([sys.executable, "-c", CHILD, str(path), program, mode], stdin=subprocess.PIPE,
                            stdout=subprocess.PIPE, text=True, bufsize=1)
    assert proc.stdout.readline().strip() == "ready"
    return proc


def _tell(proc, line="go"):
    proc.stdin.write(line + "\n")
    proc.stdin.flush()


def _finish(proc):
    if proc.poll() is None:
        _tell(proc, "exit")
    proc.communicate(timeout=60)


def _dead_pid() -> int:
    proc = subprocess.Popen([sys.executable, "-c", "pass"])
    proc.wait()
    return proc.pid


@pytest.fixture
def project(tmp_path):
    path = tmp_path / "knee.fluoro"
    path.write_text("{}", encoding="utf-8")
    return path


def _files(folder):
    return sorted(p.name for p in folder.iterdir())


def test_the_note_names_the_holder_and_both_files_go_on_release(project):
    with ProjectLock(project, "fluorogui track"):
        holder = read_holder(project)
        assert holder["program"] == "fluorogui track" and holder["pid"] == os.getpid()
        assert holder["host"] == socket.gethostname() and isinstance(holder["started"], float)
        assert lock_path(project).exists() and guard_path(project).exists()
    assert _files(project.parent) == ["knee.fluoro"]


def test_re_entrant_within_a_process(project):
    outer = ProjectLock(project, "fluorogui (desktop)").acquire()
    with ProjectLock(project, "fluorogui track"):  # the same process: no refusal
        assert read_holder(project)["program"] == "fluorogui (desktop)"
    assert read_holder(project)["program"] == "fluorogui (desktop)"  # still held by the outer one
    outer.release()
    outer.release()  # twice is harmless
    assert not lock_path(project).exists()


def test_another_process_is_refused_by_name_and_its_crash_frees_the_project(project):
    holder = _child(project, "fluorogui track")
    try:
        _tell(holder)
        assert holder.stdout.readline().strip() == "won"
        with pytest.raises(ProjectLocked) as refused:
            ProjectLock(project).acquire()
        message = str(refused.value)
        assert "in use by fluorogui track" in message and f"process {holder.pid} " in message
        assert "\n" not in message
    finally:
        holder.kill()  # a crash: no release, its note stays behind
        holder.communicate(timeout=60)
    assert read_holder(project)["pid"] == holder.pid
    with ProjectLock(project, "fluorogui (desktop)"):  # the system let go of its lock: taken over
        assert read_holder(project)["program"] == "fluorogui (desktop)"


@pytest.mark.skipif(not hasattr(os, "fork"), reason="POSIX fork")
def test_a_forked_child_is_another_process(project):
    """A child forked while the project is held is refused like any other process, and
    its exit leaves the parent's lock held."""
    import portalocker

    with ProjectLock(project, "parent"):
        pid = os.fork()
        if pid == 0:  # the child
            try:
                ProjectLock(project, "child").acquire()
                code = 1
            except ProjectLocked as exc:
                code = 0 if "in use by parent" in str(exc) else 3
            except BaseException:  # noqa: BLE001 - any other outcome is a failure code
                code = 2
            os._exit(code)
        _, status = os.waitpid(pid, 0)
        assert os.waitstatus_to_exitcode(status) == 0
        with open(guard_path(project), "rb") as other, pytest.raises(portalocker.AlreadyLocked):
            portalocker.lock(other, portalocker.LockFlags.EXCLUSIVE | portalocker.LockFlags.NON_BLOCKING)
        assert read_holder(project)["program"] == "parent"
    assert _files(project.parent) == ["knee.fluoro"]


def test_a_note_of_a_dead_process_is_taken_over(project):
    lock_path(project).write_text(json.dumps({"program": "fluorogui track", "pid": _dead_pid(),
                                              "host": socket.gethostname(), "since": 0}))
    with ProjectLock(project, "fluorogui (desktop)"):
        assert read_holder(project)["pid"] == os.getpid()


def test_a_note_of_a_live_process_without_the_lock_is_respected(project):
    """An earlier fluorogui locked by the note alone: a live process it names keeps the
    project - unless the note's start time shows the id now belongs to another process."""
    note = {"program": "fluorogui 0.0", "pid": os.getppid(), "host": socket.gethostname(), "since": 0}
    lock_path(project).write_text(json.dumps(note))
    with pytest.raises(ProjectLocked, match="in use by fluorogui 0.0"):
        ProjectLock(project).acquire()
    assert read_holder(project) == note and _files(project.parent) == ["knee.fluoro", "knee.fluoro.lock"]
    lock_path(project).write_text(json.dumps({**note, "started": 12345.0}))  # the id was reused since
    with ProjectLock(project):
        assert read_holder(project)["pid"] == os.getpid()


def test_another_hosts_note_is_respected_unless_it_is_our_own_runs(project):
    note = {"program": "fluorogui batch", "pid": 4321, "host": "elsewhere.invalid", "since": 0, "token": "run-7"}
    lock_path(project).write_text(json.dumps(note))
    with pytest.raises(ProjectLocked, match="on elsewhere.invalid"):
        ProjectLock(project, "fluorogui batch", token="run-8").acquire()
    with ProjectLock(project, "fluorogui batch", token="run-7"):  # a retried task of the same run
        assert read_holder(project)["host"] == socket.gethostname()


def test_a_note_still_being_written_does_not_free_the_project(project):
    """The race of the note-only lock: a half-written note read as 'stale'."""
    writer = _child(project, "fluorogui track", "slow-note")
    try:
        _tell(writer)
        assert writer.stdout.readline().strip() == "writing"  # holds the lock, half its note written
        with pytest.raises(ProjectLocked, match="another program"):
            ProjectLock(project).acquire()
        assert lock_path(project).read_text(encoding="utf-8") == '{"program": "fluo'  # untouched
        _tell(writer)  # let it finish its note
        assert writer.stdout.readline().strip() == "won"
        with pytest.raises(ProjectLocked, match=f"in use by fluorogui track \\(process {writer.pid} "):
            ProjectLock(project).acquire()
    finally:
        _finish(writer)
    assert writer.returncode == 0 and _files(project.parent) == ["knee.fluoro"]


def test_processes_taking_over_a_stale_lock_at_once_only_one_wins(project):
    lock_path(project).write_text(json.dumps({"program": "fluorogui track", "pid": _dead_pid(),
                                              "host": socket.gethostname(), "since": 0}))
    takers = [_child(project, f"taker {k}", "slow-read") for k in range(4)]
    try:
        for proc in takers:  # all four are waiting; release them together
            _tell(proc)
        answers = [proc.stdout.readline().strip() for proc in takers]
        winners = [k for k, answer in enumerate(answers) if answer == "won"]
        assert len(winners) == 1, answers
        assert all(answer.startswith("lost ") and "in use by" in answer
                   for k, answer in enumerate(answers) if k not in winners), answers
        assert read_holder(project)["program"] == f"taker {winners[0]}"
    finally:
        for proc in takers:
            _finish(proc)
    assert _files(project.parent) == ["knee.fluoro"]


def test_a_folder_that_cannot_hold_the_lock_gives_one_line(tmp_path):
    with pytest.raises(InputError) as failed:
        ProjectLock(tmp_path / "missing" / "knee.fluoro").acquire()
    assert "cannot create the lock file" in str(failed.value) and "\n" not in str(failed.value)
