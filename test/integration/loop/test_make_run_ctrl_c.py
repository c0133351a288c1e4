"""`make run`, then Ctrl-C in its terminal: the launch stops and make exits 0, as plain
roslaunch does (the README and docs/loop.md's table of ends say so). make used to end with 130:
roslaunch ran in make's process group, so Ctrl-C interrupted make too (tools/foreground.py).

A real terminal: `make run` runs in a pseudo-terminal that is its controlling terminal, and
the test types Ctrl-C into it (the terminal's line discipline sends SIGINT to its foreground
process group, as a user's terminal does). The stack runs headless on private ports."""
import os
import pty
import select
import signal
from pathlib import Path

from private_launch import private_launch

ROOT = Path(__file__).resolve().parents[3]
STEP_BLOCK = b"------------------------------ step 0 ------------------------------"


def test_ctrl_c_in_make_run_s_terminal_ends_it_with_status_0(tmp_path):
    (master, pomdp, human), env = private_launch(tmp_path)
    args = (f"-p {master} pomdp_port:={pomdp} human_port:={human} viz:=false "
            "on_episode_end:=wait step_delay:=0")
    pid, terminal = pty.fork()
    if pid == 0:    # the child: a session of its own, the pty its controlling terminal
        os.chdir(ROOT)
        os.execvpe("make", ["make", "-s", "run", f"ARGS={args}"], env)
    shown = b""
    try:
        while STEP_BLOCK not in shown:
            ready, _, _ = select.select([terminal], [], [], 300)
            assert ready, shown.decode(errors="replace")[-3000:]     # nothing for 5 minutes
            try:
                chunk = os.read(terminal, 65536)
            except OSError:          # the terminal closed: make ended before the first step
                chunk = b""
            assert chunk, shown.decode(errors="replace")[-3000:]
            shown += chunk
        os.write(terminal, b"\x03")                      # Ctrl-C
        while True:                  # read to the end, so that no write blocks on a full pty
            try:
                if not os.read(terminal, 65536):
                    break
            except OSError:
                break
        _, status = os.waitpid(pid, 0)
        pid = 0
        assert os.waitstatus_to_exitcode(status) == 0, shown.decode(errors="replace")[-3000:]
    finally:
        if pid:
            os.killpg(pid, signal.SIGINT)     # make's group; roslaunch's own stops with it
            os.waitpid(pid, 0)
        os.close(terminal)
