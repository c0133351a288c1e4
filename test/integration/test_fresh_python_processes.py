"""What a fresh Python process imports or computes, checked in a child process of its own (a
module already imported by this test process would hide an import): the robot process and the
pre-flight without scipy.stats, the plots without pyplot or a display, the protocol without a
websocket library, the fuzz frames the same under any hash seed."""
import os
import subprocess
import sys
from pathlib import Path

#: test/rostest's fuzz frames (rostest runs that folder's files as scripts: no package).
FUZZ_FRAMES = Path(__file__).resolve().parents[1] / "rostest"


def test_a_robot_process_that_scores_nothing_does_not_import_scipy_stats():
    # scipy.stats is most of a robot process's import time; the launch's pre-flight and a
    # fixed, random or bandit selector never score a Gaussian (docs/performance.md). Nor
    # scipy.special (0.1 s), until a posterior is updated.
    code = ("import sys, ros_hrc.processes.despot_pomdp, ros_hrc.commands.check, "
            "ros_hrc.processes.selection; "
            "sys.exit(bool({'scipy.stats', 'scipy.special'} & set(sys.modules)))")
    assert subprocess.run([sys.executable, "-c", code], timeout=120).returncode == 0


def test_the_plots_need_no_display_and_leave_pyplot_alone(tmp_path):
    code = ("import sys; from ros_hrc.experiment import plots, statistics, store; "
            "rows = [store.EpisodeRow('h', 'p', 0, 0, 1, 'human', 'success', 3, 1.0, 0.0, 0, 0, "
            "0, 1.0, 1.0)]; "
            f"plots.plot_outcomes(statistics.summarize(rows), {str(tmp_path / 'o.png')!r}); "
            "assert 'matplotlib.pyplot' not in sys.modules; "
            "assert not {'rospy', 'pybullet'} & set(sys.modules)")
    env = {k: v for k, v in os.environ.items() if k not in ("DISPLAY", "MPLBACKEND")}
    subprocess.run([sys.executable, "-c", code], check=True, env=env)
    assert (tmp_path / "o.png").read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"


def test_the_protocol_module_imports_no_websocket_library():
    code = "import sys, ros_hrc.link.protocol; print(sorted(sys.modules))"
    out = subprocess.run([sys.executable, "-c", code], check=True, capture_output=True,
                         text=True).stdout
    assert "websockets" not in out and "'websocket'" not in out and "rospy" not in out


def test_the_frames_do_not_depend_on_the_process_or_its_hash_seed():
    code = (f"import sys; sys.path.insert(0, {str(FUZZ_FRAMES)!r}); import hashlib, "
            "fuzz_frames as ff; h = hashlib.sha256()\n"
            "for f in ff.generate('7:pomdp', 300): h.update(f.payload)\n"
            "print(h.hexdigest())")
    hashes = {subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                             env=dict(os.environ, PYTHONHASHSEED=hash_seed),
                             check=True).stdout.strip() for hash_seed in ("1", "2", "3")}
    assert len(hashes) == 1 and len(hashes.pop()) == 64


def test_pillow_tabulate_and_scipy_stats_wait_for_a_snapshot_and_a_summary():
    # Pillow (~70 ms to import) writes snapshots, tabulate (~200 ms) the summary's tables and
    # scipy.stats (~1.3 s of CPU) its intervals and tests: none is on a node's start, a step's
    # path or hrc_experiment's start (docs/performance.md, issue #41).
    code = ("import sys, ros_hrc.world.scene, ros_hrc.experiment.cli, ros_hrc.loop.runner; "
            "sys.exit(bool({'PIL', 'tabulate', 'scipy.stats'} & set(sys.modules)))")
    assert subprocess.run([sys.executable, "-c", code], timeout=120).returncode == 0
