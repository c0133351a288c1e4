"""hrc_experiment on a results disk that fills up, through the real stack: a small tmpfs of the
test's own is mounted for the results (the tests run as root; they are skipped, saying so,
where mounting is not permitted) and filled while the run goes.

What a user must get: the run stops by itself in one line naming the disk and what was kept
(not a silent hang: before, the guard froze roslaunch and never killed it, and the run waited
600 s per attempt), a non-zero status, nothing left running, every kept episode whole; the
same command resumes elsewhere or once there is room, and no results file is left
half-written under its name."""
import csv
import importlib.util
import os
import re
import shutil
import subprocess
import sys
import threading
import time
import warnings
from pathlib import Path

import pytest

from result_rows import rows_of
from ros_hrc.experiment.disk import DiskWatch, mount_point
from ros_hrc.experiment.store import ResultsStore, ResultsWarning

HAS_STACK = importlib.util.find_spec("rospy") is not None and shutil.which("roslaunch")
pytestmark = [pytest.mark.skipif(not HAS_STACK, reason="needs the built stack"),
              # One pytest worker for the module: its filled run (a module fixture) is then
              # made once, not once on each worker (two stacks, 20-30 s, each time).
              pytest.mark.xdist_group("full_disk")]

#: Long enough for a grid of these sizes on a loaded machine; a run that hangs (as before the
#: fix, for good) ends the test here.
RUN_TIMEOUT = 420
#: A progress bar's line on stderr (tqdm redraws it with carriage returns).
BAR = re.compile(r"^hrc_experiment: +\d+%\|")


def mount_small_disk(where: Path, size: str) -> None:
    """A tmpfs of ``size`` at ``where``, or the test is skipped saying why."""
    where.mkdir()
    done = subprocess.run(["mount", "-t", "tmpfs", "-o", f"size={size}", "tmpfs", str(where)],
                          capture_output=True, text=True)
    if done.returncode != 0:
        pytest.skip(f"cannot mount a small tmpfs for the results (needs root): "
                    f"{done.stderr.strip()}")


def processes_using(path: Path) -> list:
    """Processes whose command line or environment names ``path`` (a cell's worker, its
    roslaunch, roscore and nodes: ROS_LOG_DIR is under the results)."""
    found = []
    marker = str(path).encode()
    for entry in os.listdir("/proc"):
        if not entry.isdigit() or int(entry) == os.getpid():
            continue
        for part in ("cmdline", "environ"):
            try:
                with open(f"/proc/{entry}/{part}", "rb") as f:
                    if marker in f.read():
                        found.append(int(entry))
                        break
            except OSError:
                continue
    return found


def release_disk(where: Path) -> None:
    """Whatever a failed test left on the disk is killed, and the disk unmounted."""
    for pid in processes_using(where):
        try:
            os.kill(pid, 9)
        except ProcessLookupError:
            pass
    subprocess.run(["umount", "-l", str(where)], capture_output=True)


def fill(disk: Path) -> None:
    """Fill ``disk`` to the last byte (a file ``filler`` on it)."""
    with open(disk / "filler", "wb", buffering=0) as f:
        for chunk in (1 << 16, 1 << 12, 1):
            try:
                while True:
                    f.write(b"\0" * chunk)
            except OSError:
                continue


def fill_when_recorded(episodes_csv: Path, rows: int, disk: Path) -> threading.Thread:
    """A thread that fills ``disk`` once ``episodes_csv`` holds ``rows`` episodes (the run
    is under way, its stacks writing their logs)."""
    def wait_then_fill() -> None:
        while True:
            try:
                if episodes_csv.read_text().count("\n") > rows:
                    break
            except OSError:
                pass
            time.sleep(0.02)
        fill(disk)
    thread = threading.Thread(target=wait_then_fill, daemon=True)
    thread.start()
    return thread


def experiment(grid, out, cwd):
    return subprocess.run([sys.executable, "-m", "ros_hrc.experiment.cli", *grid, "--out", out],
                          capture_output=True, text=True, timeout=RUN_TIMEOUT, cwd=cwd,
                          stdin=subprocess.DEVNULL)


def said(stderr: str) -> list:
    """The lines on stderr, without the progress bar's redrawings."""
    lines = [line.split("\r")[-1].strip() for line in stderr.split("\n")]
    return [line for line in lines if line and not BAR.match(line)]


def the_line(done, disk: Path) -> str:
    """The one line a run that stopped on a full disk said, its head checked here (the disk,
    and how it was seen: the room left on it, or a write that found none); the rest
    returned: what was kept and how to resume."""
    lines = said(done.stderr)
    assert len(lines) == 1, done.stderr[-3000:]
    head = re.match(r"hrc_experiment: the disk at (\S+) is full \((\d+ KiB left|No space "
                    r"left on device: \S+)\): ", lines[0])
    assert head and head.group(1) == str(disk), lines[0]
    return lines[0][head.end():]


def whole_episodes(out: Path) -> list:
    """The episodes of a results directory, checked whole: the store opens it without cutting
    anything, and every episode has all its steps."""
    with warnings.catch_warnings():
        warnings.simplefilter("error", ResultsWarning)
        store = ResultsStore(out)
    episodes = store.episodes()
    steps = {}
    for step in store.steps():
        steps.setdefault(step.key, []).append(step.step)
    for row in episodes:
        assert steps.get(row.key) == list(range(row.steps)), f"episode {row.key} is not whole"
    assert set(steps) == {row.key for row in episodes}
    return episodes


#: Two cells on one stack (the driver writes every row, whatever the stacks: one is enough to
#: fill the disk under a run, and each stack more costs its start, about 8 s of CPU).
GRID = ["--human-models", "tired", "--policies", "no_robot", "--seeds", "0,1", "--episodes",
        "12", "--step-limit", "3", "--jobs", "1", "--no-plots"]


@pytest.fixture(scope="module")
def filled_run(tmp_path_factory):
    """The grid run onto a disk filled once 2 episodes are in: (the run, its disk, its --out
    as typed, the directory it ran in). The disk stays as the run left it, for every test."""
    where = tmp_path_factory.mktemp("full_disk")
    disk = where / "disk"
    mount_small_disk(disk, "8m")
    try:
        filler = fill_when_recorded(disk / "res" / "episodes.csv", 2, disk)
        done = experiment(GRID, "disk/res", cwd=where)
        filler.join(10)
        yield done, disk, where
    finally:
        release_disk(disk)


def test_a_disk_that_fills_during_a_run_stops_it_in_one_line_keeping_whole_episodes(filled_run):
    done, disk, where = filled_run
    out = disk / "res"
    assert done.returncode == 1, done.stderr[-3000:]
    kept = whole_episodes(out)
    assert len(kept) >= 2
    assert the_line(done, disk) == (
        f"{len(kept)} whole episodes kept in {out}; resume with: hrc_experiment "
        f"{' '.join(GRID)} --out disk/res once there is room on {disk} (or copy {out} to "
        "another disk and give --out that copy)")
    assert "Traceback" not in done.stdout + done.stderr
    assert processes_using(disk) == [], "a stack (worker, roslaunch, roscore, node) runs on"


def test_a_run_stopped_by_a_full_disk_resumes_elsewhere_keeping_every_whole_episode(
        filled_run, tmp_path):
    done, disk, _ = filled_run
    kept = rows_of(disk / "res" / "episodes.csv")
    elsewhere = tmp_path / "res"
    shutil.copytree(disk / "res", elsewhere)
    again = experiment(GRID, str(elsewhere), cwd=tmp_path)
    assert again.returncode == 0, again.stderr[-3000:]
    assert f"24 episodes; {len(kept)} already in {elsewhere}, {24 - len(kept)} to run" \
        in again.stdout
    episodes = whole_episodes(elsewhere)
    assert sorted((row.seed, row.episode) for row in episodes) == \
        [(seed, n) for seed in (0, 1) for n in range(12)]
    resumed = rows_of(elsewhere / "episodes.csv")
    assert resumed[:len(kept)] == kept, "a kept episode was changed or dropped"


def test_a_disk_full_while_writing_the_summary_is_one_line_and_leaves_no_half_file(tmp_path):
    """The disk fills once every episode is in: the run stops (while its stacks shut down,
    or when it writes run.json, the summary or a plot) in the same one line, and no final
    file is there half-written; once there is room, the same command writes them all."""
    disk = tmp_path / "disk"
    mount_small_disk(disk, "8m")
    grid = ["--human-models", "tired", "--policies", "no_robot", "--seeds", "0",
            "--episodes", "2", "--step-limit", "3", "--jobs", "1"]
    try:
        filler = fill_when_recorded(disk / "res" / "episodes.csv", 2, disk)
        done = experiment(grid, "disk/res", cwd=tmp_path)
        filler.join(10)
        out = disk / "res"
        assert done.returncode == 1, done.stderr[-3000:]
        assert the_line(done, disk) == (
            f"2 whole episodes kept in {out}; resume with: hrc_experiment {' '.join(grid)} "
            f"--out disk/res once there is room on {disk} (or copy {out} to another disk and "
            "give --out that copy)")
        assert len(whole_episodes(out)) == 2
        finals = ("summary.csv", "summary.md", "run.json", "outcomes.png", "success.png",
                  "belief.png")
        for name in os.listdir(out):
            assert not name.endswith(".part"), f"{name}: a temporary file was left"
            assert name not in finals, f"{name} was written on a full disk"
        assert processes_using(disk) == []

        (disk / "filler").unlink()      # room again: the same command writes what is missing
        again = experiment(grid, "disk/res", cwd=tmp_path)
        assert again.returncode == 0, again.stderr[-3000:]
        assert "2 already in" in again.stdout and "0 to run" in again.stdout
        with open(out / "summary.csv", newline="") as f:
            assert [row["robot_policy"] for row in csv.DictReader(f)][:1] == ["no_robot"]
        assert (out / "summary.md").read_text().strip()
    finally:
        release_disk(disk)


def test_the_watch_names_the_disk_that_has_no_room_left(tmp_path):
    disk = tmp_path / "disk"
    mount_small_disk(disk, "1m")
    try:
        (disk / "res" / "logs").mkdir(parents=True)
        assert mount_point(disk / "res" / "logs" / "not_yet.log") == disk
        watch = DiskWatch([disk / "res", disk / "res" / "logs", tmp_path])
        assert sorted(map(str, watch.disks.values())) == sorted({str(disk),
                                                                 str(mount_point(tmp_path))})
        assert watch.full() is None
        fill(disk)
        full = watch.full()
        assert full is not None and full.mount == str(disk)
        assert str(full) == f"the disk at {disk} is full (0 KiB left)"
    finally:
        release_disk(disk)


def test_the_full_disk_line_counts_what_the_run_keeps_in_its_own_unit(tmp_path):
    """A sequence study keeps whole sequences, not episodes: the line says which."""
    from ros_hrc.experiment.disk import DiskFull, full_disk_line
    from ros_hrc.experiment.sequence_rows import SequenceStore
    full = DiskFull(tmp_path, "12 KiB left")
    assert "3 whole sequences kept in" in full_disk_line(
        "hrc_experiment", full, 3, tmp_path / "out", "hrc_experiment ...", SequenceStore.UNIT)
    assert "1 whole sequence kept in" in full_disk_line(
        "hrc_experiment", full, 1, tmp_path / "out", "hrc_experiment ...", SequenceStore.UNIT)
    assert "1 whole episode kept in" in full_disk_line(
        "hrc_experiment", full, 1, tmp_path / "out", "hrc_experiment ...", ResultsStore.UNIT)
