"""free_port picks below the kernel's ephemeral range, where no client socket or server bound
to port 0 (another stack's roslaunch) can take the port before its stack binds it."""
import socket

from ros_hrc.link import session
from ros_hrc.link.transport import free_port


def test_a_picked_port_is_below_the_ephemeral_range_and_can_be_bound():
    low = session._ephemeral_low()
    for _ in range(20):
        port = free_port()
        assert port < low
        with socket.socket() as s:
            s.bind(("127.0.0.1", port))


def test_with_no_room_below_the_ephemeral_range_the_kernel_picks(monkeypatch):
    monkeypatch.setattr(session, "_ephemeral_low", lambda: 1024)
    assert 0 < free_port() < 65536
