"""The link's files and server against other processes: a launch's token is pruned once the
launcher that minted it has ended, and a server that ran out of file descriptors serves again
once they are back (a child process of the test's own, starved of descriptors)."""
import os
import socket
import subprocess
import sys
import textwrap
import time

from ros_hrc.link.protocol import Hello, Reset, decode, encode
from ros_hrc.link.token import launcher_of, mint_token, prune_tokens
from raw_client import RawConnection

#: A safety net for a server that never answers; no test asserts a time.
SAFETY = 10.0


def test_tokens_of_ended_launches_are_pruned_and_live_ones_kept(tmp_path):
    home = {"ROS_HOME": str(tmp_path / "ros_home")}
    ended = subprocess.run([sys.executable, "-c", "import os; print(os.getpid())"],
                           capture_output=True, text=True, check=True)
    gone = mint_token("gone", launcher_pid=int(ended.stdout), environ=home)
    live = mint_token("live", launcher_pid=os.getpid(), environ=home)
    unknown = mint_token("unknown", environ=home)
    assert prune_tokens(home) == 1
    assert not gone.exists() and live.exists() and unknown.exists()


def test_a_token_whose_launcher_is_a_zombie_is_pruned(tmp_path):
    """A launcher that ended but is not reaped yet (a zombie) has ended: os.kill(pid, 0)
    said it was alive, and its token stayed."""
    import psutil
    home = {"ROS_HOME": str(tmp_path / "ros_home")}
    child = subprocess.Popen([sys.executable, "-c", "pass"])
    try:
        deadline = time.monotonic() + SAFETY
        while psutil.Process(child.pid).status() != psutil.STATUS_ZOMBIE:
            assert time.monotonic() < deadline, "the child never ended"
            time.sleep(0.02)
        zombie = mint_token("zombie", launcher_pid=child.pid, environ=home)
        assert launcher_of(zombie) == child.pid
        assert prune_tokens(home) == 1 and not zombie.exists()
    finally:
        child.wait()


def test_the_launcher_is_read_from_the_tokens_second_line_or_is_none(tmp_path):
    home = {"ROS_HOME": str(tmp_path / "ros_home")}
    assert launcher_of(mint_token("with", launcher_pid=4321, environ=home)) == 4321
    assert launcher_of(mint_token("without", environ=home)) is None
    assert launcher_of(tmp_path / "missing.token") is None


# -- the accept loop survives running out of file descriptors -------------------------------

SERVER_WITHOUT_FDS = textwrap.dedent("""
    import os, resource, sys
    from ros_hrc.link.protocol import Ack, DispatchTable, Reset
    from ros_hrc.link.transport import MessageServer
    table = DispatchTable("hrc_robot")
    table.on(Reset, lambda msg, peer: Ack(step=0, of="reset"))
    server = MessageServer(0, table, name="hrc_robot").start()
    resource.setrlimit(resource.RLIMIT_NOFILE, (64, 64))
    held = []
    try:
        while True:
            held.append(os.open(os.devnull, os.O_RDONLY))
    except OSError:
        pass
    print(server.port, flush=True)
    sys.stdin.readline()            # a client now waits, unaccepted: EMFILE
    for fd in held:
        os.close(fd)
    print("released", flush=True)
    sys.stdin.readline()
    server.stop()
""")


def test_the_server_serves_again_once_file_descriptors_are_back():
    """Before: accept() failing with EMFILE ended websockets' accept loop; the socket still
    listened but nobody was ever served again."""
    proc = subprocess.Popen([sys.executable, "-c", SERVER_WITHOUT_FDS], stdin=subprocess.PIPE,
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    try:
        port = int(proc.stdout.readline())
        # The TCP connection is queued by the kernel; accept() fails in the server.
        sock = socket.create_connection(("127.0.0.1", port), timeout=SAFETY)
        time.sleep(0.5)   # let accept() fail a few times (the behaviour under test)
        proc.stdin.write("go\n")
        proc.stdin.flush()
        assert proc.stdout.readline().strip() == "released"
        sock.close()
        ws = RawConnection(f"ws://127.0.0.1:{port}", SAFETY)
        ws.send(encode(Hello(who="test")))
        assert isinstance(decode(ws.recv()), Hello)
        ws.send(encode(Reset(id=1)))
        assert decode(ws.recv()).reply_to == 1
        ws.close()
        proc.stdin.write("stop\n")
        proc.stdin.flush()
        assert proc.wait(SAFETY) == 0
    finally:
        if proc.poll() is None:
            proc.kill()
            proc.wait()
    err = proc.stderr.read()
    assert "cannot accept a connection: [Errno 24] Too many open files" in err, err
    assert "accepting connections again" in err, err
