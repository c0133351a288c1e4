"""hrc_experiment as its tests run it: the command line, and a stand-in ``roslaunch`` first on
PATH that records each start and how it was stopped (``fake_ros``), so a test sees exactly
which stacks the experiment would start."""
import os
import sys

import pytest


FAKE_ROSLAUNCH = """#!/bin/sh
echo "start $$ $*" >> "$FAKE_ROSLAUNCH_LOG"
trap 'echo "SIGINT $$" >> "$FAKE_ROSLAUNCH_LOG"; exit 0' INT
trap 'echo "SIGTERM $$" >> "$FAKE_ROSLAUNCH_LOG"; exit 0' TERM
while :; do sleep 0.1; done
"""


@pytest.fixture
def fake_ros(tmp_path):
    """An environment whose ``roslaunch`` only records; returns (env, its log)."""
    bin_dir = tmp_path / "bin"
    bin_dir.mkdir()
    script = bin_dir / "roslaunch"
    script.write_text(FAKE_ROSLAUNCH)
    script.chmod(0o755)
    log = tmp_path / "roslaunch.log"
    env = dict(os.environ, PATH=f"{bin_dir}{os.pathsep}{os.environ.get('PATH', '')}",
               FAKE_ROSLAUNCH_LOG=str(log))
    return env, log


def experiment(*args):
    return [sys.executable, "-m", "ros_hrc.experiment.cli", *args]
