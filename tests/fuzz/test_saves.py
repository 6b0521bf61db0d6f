"""Saves that lose nothing: kills during a save, a full disk, symlinks, file modes, temps."""
from __future__ import annotations

import os
import stat

import pytest
from fuzz_harness import full_disk_trials, kill_trials, leftover_temps

from fluorogui.io.errors import InputError
from fluorogui.io.files import atomic_write_text, clean_stale_temps

posix_only = pytest.mark.skipif(os.name != "posix", reason="kills and RLIMIT_FSIZE are POSIX")


@posix_only
def test_kills_during_save_lose_nothing(tmp_path):
    counts = kill_trials(tmp_path, trials=10, seed=1)
    assert counts == {"trials": 10, "lost_or_truncated_project": 0, "lost_or_truncated_backup": 0,
                      "leftover_temps_after_next_save": 0, "temps_left_by_kills": counts["temps_left_by_kills"]}


@posix_only
def test_full_disk_saves_fail_cleanly(tmp_path):
    counts = full_disk_trials(tmp_path, limits=[1, 4096, 300_000])
    assert counts == {"trials": 3, "lost_or_truncated_project": 0, "lost_or_truncated_backup": 0,
                      "leftover_temps": 0, "unclear_messages": 0, "accepted": 0}


def test_symlink_is_kept_and_its_target_replaced(tmp_path):
    real = tmp_path / "real"
    real.mkdir()
    atomic_write_text(real / "p.fluoro", "one\n")
    link = tmp_path / "p.fluoro"
    link.symlink_to(real / "p.fluoro")
    atomic_write_text(link, "two\n", backup=True)
    assert link.is_symlink() and link.read_text() == "two\n"
    assert (real / "p.fluoro").read_text() == "two\n"
    assert (real / "p.fluoro.bak").read_text() == "one\n"
    assert not leftover_temps(real, "p.fluoro") and not leftover_temps(tmp_path, "p.fluoro")


def test_mode_is_kept_and_new_files_follow_the_umask(tmp_path):
    path = tmp_path / "shared.fluoro"
    path.write_text("one\n")
    os.chmod(path, 0o664)
    atomic_write_text(path, "two\n", backup=True)
    assert stat.S_IMODE(path.stat().st_mode) == 0o664
    old = os.umask(0o022)
    try:
        atomic_write_text(tmp_path / "new.fluoro", "x\n")
    finally:
        os.umask(old)
    assert stat.S_IMODE((tmp_path / "new.fluoro").stat().st_mode) == 0o644


def test_backup_is_a_new_name_for_the_old_file_not_a_rewrite(tmp_path):
    path = tmp_path / "p.fluoro"
    atomic_write_text(path, "one\n")
    first_inode = path.stat().st_ino
    atomic_write_text(path, "two\n", backup=True)
    bak = tmp_path / "p.fluoro.bak"
    assert bak.read_text() == "one\n" and bak.stat().st_ino == first_inode
    bak_inode = bak.stat().st_ino
    atomic_write_text(path, "three\n", backup=True)
    assert bak.read_text() == "two\n" and bak.stat().st_ino != bak_inode  # replaced, not rewritten


def test_stale_temps_are_removed_live_ones_kept(tmp_path):
    path = tmp_path / "p.fluoro"
    dead = tmp_path / ".p.fluoro.999999999.abc.tmp"        # a process id that cannot run
    dead_bak = tmp_path / ".p.fluoro.bak999999999.abc.tmp"
    live = tmp_path / f".p.fluoro.{os.getppid()}.abc.tmp"  # a running process's save
    old_style = tmp_path / ".p.fluoro.x1y2z3.tmp"           # no owner: removed once old
    other = tmp_path / ".other.fluoro.999999999.abc.tmp"
    for p in (dead, dead_bak, live, old_style, other):
        p.write_text("partial")
    os.utime(old_style, (0, 0))
    assert clean_stale_temps(path) == 3
    assert sorted(p.name for p in tmp_path.iterdir()) == sorted([live.name, other.name])


def test_unwritable_folder_names_the_file(tmp_path):
    if os.geteuid() == 0:
        pytest.skip("root writes anywhere")
    os.chmod(tmp_path, 0o500)
    try:
        with pytest.raises(InputError, match="could not save: permission denied"):
            atomic_write_text(tmp_path / "p.fluoro", "x")
    finally:
        os.chmod(tmp_path, 0o700)


def test_save_after_a_kill_between_the_renames_leaves_no_temp(tmp_path):
    path = tmp_path / "p.fluoro"
    atomic_write_text(path, "one\n")
    os.link(path, tmp_path / "p.fluoro.bak")  # backup and project are one file, as after such a kill
    atomic_write_text(path, "two\n", backup=True)
    assert (tmp_path / "p.fluoro.bak").read_text() == "one\n" and path.read_text() == "two\n"
    assert not leftover_temps(tmp_path, "p.fluoro")


def test_opening_a_project_removes_temps_of_dead_saves(tmp_path):
    from fluorogui.io.project.document import load_project

    path = tmp_path / "p.fluoro"
    path.write_text("{}")
    (tmp_path / ".p.fluoro.999999999.abc.tmp").write_text("partial")
    with pytest.raises(InputError):
        load_project(path)
    assert not leftover_temps(tmp_path, "p.fluoro")
