"""Start-up with real processes: a roscore on a private port, the real hrc_human, an MDP
client of its port, and a stand-in for the world and the POMDP process (a small rospy node
offering the world's services, and a websocket server on the POMDP's port) that starts late,
as a GUI world under load does.

hrc_human must say, while it waits, which services and which link it waits for; the MDP must
get no reset (so it takes no step) before they are up; then step 0 is carried out, once."""
import os
import subprocess
import sys
import textwrap
import time
from pathlib import Path

import pytest

from ros_hrc.link.protocol import Ack, Reset, Step
from ros_hrc.link.transport import LinkTimeout, MessageClient, free_port, link_url

ROOT = Path(__file__).resolve().parents[3]

FAKE_WORLD = textwrap.dedent('''
    """The world's services and the POMDP process's link (its port and the link token's file
    are the arguments), answering at once; prints each call."""
    import sys
    import threading
    import rospy
    from std_srvs.srv import Trigger, TriggerResponse
    from ros_hrc.link.protocol import Ack, Decision, DispatchTable, Observation, Reset
    from ros_hrc.link.token import read_token
    from ros_hrc.link.transport import MessageServer
    from ros_hrc.msg import WorldState
    from ros_hrc.srv import GetWorldState, GetWorldStateResponse
    from ros_hrc.nodes.human_node import WORLD_SERVICES

    PRINT_LOCK = threading.Lock()

    def say(*parts):
        # rospy answers each service on its own thread; print() writes its pieces one by
        # one, so two calls at once could interleave into one garbled line.
        with PRINT_LOCK:
            sys.stdout.write(" ".join(str(part) for part in parts) + "\\n")
            sys.stdout.flush()

    def trigger(name):
        def handler(_req):
            say("called", name)
            return TriggerResponse(success=True, message=name + " done")
        return handler

    def state(_req):
        return GetWorldStateResponse(state=WorldState(sim_time=1.0, holder="none",
                                                      object_visible=True))

    def decide(msg, _peer):
        say("observation", msg.epoch, msg.step)
        return Decision(step=msg.step, action="rIdle", belief_states=["S0"], belief=[1.0])

    def reset_planner(msg, _peer):
        say("reset of the planner", msg.epoch)
        return Ack(step=0, of=Reset.TYPE, result="belief reset")

    rospy.init_node("fake_world", disable_signals=True)
    keep = [rospy.Service(name, Trigger, trigger(name)) for name in WORLD_SERVICES
            if name != "/hrc/world/state"]
    keep.append(rospy.Service("/hrc/world/state", GetWorldState, state))
    planner = DispatchTable("fake_pomdp")
    planner.on(Observation, decide)
    planner.on(Reset, reset_planner)
    pomdp = MessageServer(int(sys.argv[1]), planner, name="fake_pomdp",
                          token=read_token(sys.argv[2])).start()
    say("fake world up")
    sys.stdin.read()   # until the test closes our stdin
''')


def wait_for_port(port, timeout=30.0):
    import socket
    deadline = time.monotonic() + timeout
    while time.monotonic() < deadline:
        with socket.socket() as s:
            if s.connect_ex(("127.0.0.1", port)) == 0:
                return True
        time.sleep(0.1)
    return False


def stop(proc):
    if proc is not None and proc.poll() is None:
        proc.terminate()
        try:
            proc.wait(10)
        except subprocess.TimeoutExpired:
            proc.kill()
            proc.wait(5)


@pytest.fixture
def ros(tmp_path):
    """A private roscore; yields (env, start) where start(cmd, name) runs a process whose
    output goes to tmp_path/name.log; everything started is stopped by its pid."""
    master = free_port()
    env = dict(os.environ, ROS_MASTER_URI=f"http://127.0.0.1:{master}",
               ROS_LOG_DIR=str(tmp_path / "log"), PYTHONUNBUFFERED="1")
    env.pop("DISPLAY", None)
    procs = []

    def start(cmd, name, stdin=subprocess.DEVNULL):
        log = open(tmp_path / f"{name}.log", "w")
        proc = subprocess.Popen(cmd, env=env, stdin=stdin, stdout=log,
                                stderr=subprocess.STDOUT, text=True)
        procs.append(proc)
        return proc

    core = start(["roscore", "-p", str(master)], "roscore")
    assert wait_for_port(master), "roscore did not start"
    try:
        yield env, start
    finally:
        for proc in reversed(procs):
            if proc is not core:
                if proc.stdin:
                    proc.stdin.close()
                stop(proc)
        stop(core)


def read(tmp_path, name):
    path = tmp_path / f"{name}.log"
    return path.read_text() if path.exists() else ""


def wait_for_text(tmp_path, name, text, timeout=30.0):
    deadline = time.monotonic() + timeout
    while time.monotonic() < deadline:
        if text in read(tmp_path, name):
            return True
        time.sleep(0.1)
    return False


def test_a_late_world_is_waited_for_and_step_0_is_carried_out_once(ros, tmp_path, link_token):
    env, start = ros
    token, token_file = link_token
    human_port, pomdp_port = free_port(), free_port()
    start([sys.executable, str(ROOT / "scripts" / "hrc_human"), f"_human_port:={human_port}",
           f"_pomdp_port:={pomdp_port}", "_read_stdin:=false", "_wait_report_every:=1.0",
           f"_token_file:={token_file}"],
          "hrc_human")
    mdp = MessageClient(link_url(human_port), "despot_mdp", connect_timeout=60.0, token=token)
    try:
        mdp.connect()
        # No world, no POMDP process: hrc_human says what it waits for, and starts no
        # episode.
        assert wait_for_text(tmp_path, "hrc_human", "waiting for the world (hrc_world): "
                             "/hrc/world/reset, /hrc/world/state, /human/attempt_grasp"), \
            read(tmp_path, "hrc_human")
        assert wait_for_text(tmp_path, "hrc_human", "; for the robot planner (despot_pomdp): "
                             f"ws://127.0.0.1:{pomdp_port} (3 s;"), \
            read(tmp_path, "hrc_human")
        with pytest.raises(LinkTimeout):
            mdp.receive(timeout=1.0, match=lambda m: isinstance(m, Reset))
        out = read(tmp_path, "hrc_human")
        assert "reset failed" not in out and "STEP FAILED" not in out, out

        # The world and the POMDP process come up: the first reset, then step 0, carried
        # out once.
        script = tmp_path / "fake_world.py"
        script.write_text(FAKE_WORLD)
        start([sys.executable, str(script), str(pomdp_port), str(token_file)], "world",
              stdin=subprocess.PIPE)
        reset = mdp.receive(timeout=60.0, match=lambda m: isinstance(m, Reset))
        assert reset.episode == 1
        assert wait_for_text(tmp_path, "hrc_human", "The world (hrc_world) and the robot planner "
                             "(despot_pomdp) are up after"), read(tmp_path, "hrc_human")
        reply = mdp.request(Step(step=0, action="graspAttempt", state="failed_to_grasp",
                                 epoch=reset.epoch), timeout=60.0)
        assert isinstance(reply, Ack) and reply.action == "rIdle", reply
        world = read(tmp_path, "world")
        assert world.count("called /human/attempt_grasp") == 1, world
        assert world.count("called /hrc/world/reset") == 1, world
        assert f"observation {reset.epoch} 0" in world, world
        out = read(tmp_path, "hrc_human")
        assert "reset failed" not in out and "STEP FAILED" not in out, out
        assert "----- step 0 -----" in out, out
    finally:
        mdp.close()


def test_with_wait_for_listener_no_episode_starts_before_someone_listens(ros, tmp_path,
                                                                         link_token):
    """Before: an experiment cell subscribed to /hrc/status after the stack had started; an
    episode of a tenth of a second could be played before it listened, and the cell failed
    ("the stack played episode 1 where episode 0 was due", about 1 cell in 130)."""
    env, start = ros
    token, token_file = link_token
    human_port, pomdp_port = free_port(), free_port()
    start([sys.executable, str(ROOT / "scripts" / "hrc_human"), f"_human_port:={human_port}",
           f"_pomdp_port:={pomdp_port}", "_read_stdin:=false", "_wait_report_every:=1.0",
           "_wait_for_listener:=true", f"_token_file:={token_file}"], "hrc_human")
    script = tmp_path / "fake_world.py"
    script.write_text(FAKE_WORLD)
    start([sys.executable, str(script), str(pomdp_port), str(token_file)], "world",
          stdin=subprocess.PIPE)
    mdp = MessageClient(link_url(human_port), "despot_mdp", connect_timeout=60.0, token=token)
    try:
        mdp.connect()
        assert wait_for_text(tmp_path, "hrc_human", "a listener (wait_for_listener)"), \
            read(tmp_path, "hrc_human")
        with pytest.raises(LinkTimeout):
            mdp.receive(timeout=2.0, match=lambda m: isinstance(m, Reset))
        start(["rostopic", "echo", "/hrc/status/step"], "listener")
        reset = mdp.receive(timeout=60.0, match=lambda m: isinstance(m, Reset))
        assert reset.episode == 1
    finally:
        mdp.close()


#: A node started the way every ros_hrc node starts (ros_hrc.nodes.common.init_node), with
#: one Trigger service; its TCPROS port is printed.
SERVICE_NODE = textwrap.dedent('''
    import sys
    import rosgraph
    import rospy
    from std_srvs.srv import Trigger, TriggerResponse
    from ros_hrc.nodes.common import init_node

    init_node("a_node", disable_signals=True)
    keep = rospy.Service("/a_node/ping", Trigger, lambda _req: TriggerResponse(True, "pong"))
    uri = rosgraph.Master("/a_node").lookupService("/a_node/ping")
    print("service at", uri, flush=True)
    sys.stdin.read()   # until the test closes our stdin
''')


def test_a_client_that_sends_no_handshake_does_not_stall_a_node(ros, tmp_path):
    """Before: rospy reads each inbound connection's header on its accepting thread with no
    time limit. A client that connected to a node's TCPROS port and sent no header (here an
    HTTP request, as from a client that held an old XML-RPC address on that port) stalled
    every later connection to the node: its services hung for good, and a whole stack stood
    still (hrc.test, on CI). Now the node takes each connection on a thread of its own."""
    import socket
    env, start = ros
    script = tmp_path / "service_node.py"
    script.write_text(SERVICE_NODE)
    start([sys.executable, str(script)], "node", stdin=subprocess.PIPE)
    assert wait_for_text(tmp_path, "node", "service at rosrpc://"), read(tmp_path, "node")
    uri = read(tmp_path, "node").split("service at rosrpc://")[1].split()[0]
    host, port = uri.rsplit(":", 1)
    stale = [socket.create_connection((host, int(port)), timeout=10) for _ in range(3)]
    try:
        stale[0].sendall(b"POST /RPC2 HTTP/1.1\r\nHost: vm\r\nContent-Length: 300\r\n\r\n")
        stale[1].sendall(b"\x10\x00")       # a header's first bytes, and no more
        # (stale[2] sends nothing at all.)
        answer = subprocess.run(["rosservice", "call", "/a_node/ping"], env=env,
                                capture_output=True, text=True, timeout=60,
                                stdin=subprocess.DEVNULL)
        assert answer.returncode == 0, answer.stderr
        assert "pong" in answer.stdout, answer.stdout
        # The stalled connections are closed by the node once their handshake is overdue.
        for sock in stale:
            sock.settimeout(60)
            try:
                assert sock.recv(100) == b"", "the node answered a connection without a handshake"
            except ConnectionResetError:   # closed with our bytes unread
                pass
    finally:
        for sock in stale:
            sock.close()
