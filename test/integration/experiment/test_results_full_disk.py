"""The results files on a disk that fills, in child processes: hrc_experiment on a real full
disk (a 256 KiB tmpfs in a mount namespace of the test's own) says so in one line; a cell whose
episode cannot be recorded stops its worker process. The in-process checks of the results
files: test/unit/experiment/test_results.py."""
import os
import subprocess
import sys

import pytest

from ros_hrc.experiment.store import ResultsStore
from result_rows import episode, steps_of


def _can_mount_a_small_disk() -> bool:
    try:
        return subprocess.run(["unshare", "-rm", "sh", "-c",
                               "mount -t tmpfs -o size=64k tmpfs /mnt 2>/dev/null || "
                               "mount -t tmpfs -o size=64k tmpfs /tmp"],
                              capture_output=True, timeout=30).returncode == 0
    except (OSError, subprocess.TimeoutExpired):
        return False


@pytest.mark.skipif(not _can_mount_a_small_disk(),
                    reason="needs a mount namespace for a small tmpfs (unshare -rm)")
def test_a_full_disk_while_writing_the_summary_is_one_line(tmp_path):
    """Before: OSError: [Errno 28] with a traceback. A real full disk: a 256 KiB tmpfs in a
    mount namespace of the test's own, filled before hrc_experiment writes its summary."""
    recorded = tmp_path / "recorded"
    store = ResultsStore(recorded)
    row = episode(human="tired", policy="no_robot", number=0)
    store.add(row, steps_of(row))
    disk = tmp_path / "disk"
    disk.mkdir()
    out = disk / "out"
    script = (f"mount -t tmpfs -o size=256k tmpfs {disk} && mkdir {out} && "
              f"cp {recorded}/episodes.csv {recorded}/steps.csv {out}/ && echo 1 > {out}/.lock "
              f"&& (dd if=/dev/zero of={disk}/filler bs=4096 2>/dev/null; true) && "
              f"exec {sys.executable} -m ros_hrc.experiment.cli --human-models tired "
              f"--policies no_robot --seeds 0 --episodes 1 --no-plots --out {out}")
    done = subprocess.run(["unshare", "-rm", "sh", "-c", script], capture_output=True,
                          text=True, timeout=120, stdin=subprocess.DEVNULL)
    assert done.returncode == 1, done.stderr
    assert done.stderr.splitlines() == [
        f"hrc_experiment: the disk at {disk} is full (No space left on device: "
        f"{out / 'summary.csv'}): 1 whole episode kept in {out}; resume with: hrc_experiment "
        f"--human-models tired --policies no_robot --seeds 0 --episodes 1 --no-plots --out "
        f"{out} once there is room on {disk} (or copy {out} to another disk and give --out "
        "that copy)"]
    assert "0 to run" in done.stdout


def test_an_episode_that_cannot_be_recorded_stops_its_worker(tmp_path, monkeypatch):
    """A full disk while an episode is appended fails the cell with the reason, and its worker
    (and so its stack) is stopped rather than left running unread."""
    import errno
    import io as text_io
    from ros_hrc.experiment import pool
    from ros_hrc.experiment.stack import CellSpec, encode_episode
    row = episode(human="tired", policy="no_robot", number=0)
    pid_file = tmp_path / "worker.pid"
    worker = (f"import os, signal, sys, time\n"
              f"open({str(pid_file)!r}, 'w').write(str(os.getpid()))\n"
              f"print({encode_episode(row, steps_of(row))!r}, flush=True)\n"
              f"while True: time.sleep(0.1)\n")
    monkeypatch.setattr(pool, "worker_command", lambda spec_file=None: [sys.executable, "-c",
                                                                         worker])

    def full(row, steps):
        raise OSError(errno.ENOSPC, "No space left on device", str(tmp_path / "episodes.csv"))
    cell = CellSpec("tired", "no_robot", 0, [0, 1], log_dir=str(tmp_path / "logs"))
    with pytest.raises(OSError, match="No space left on device"):
        pool.StackWorker(pool.Stopper()).play(cell, full, text_io.StringIO())
    pid = int(pid_file.read_text())
    with pytest.raises(ProcessLookupError):
        os.kill(pid, 0)
