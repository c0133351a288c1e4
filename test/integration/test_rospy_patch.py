"""The one rospy internal ros_hrc patches is still the one it was written for.

`ros_hrc.nodes.common.guard_inbound_connections` replaces rospy's private
`TCPROSServer._tcp_server_callback` (rospy reads each inbound handshake on its accepting thread
with no time limit; no public API sets one: docs/loop.md, "A connection without a handshake").
It wraps the original, so it relies on two facts of rospy 1.15.15 (Debian's python3-rospy):
the server hands `_tcp_server_callback` to its `TCPServer` when it starts (so patching the class
before `init_node` takes effect), and the callback reads the header itself. When Debian ships
another rospy, these tests fail: read the new callback, check the wrapper still fits, then
update the pins.
"""
import hashlib
import importlib.metadata
import inspect

from rospy.impl import tcpros_base

#: The rospy release the patch was written for.
ROSPY_VERSION = "1.15.15"
#: sha256 of inspect.getsource(TCPROSServer._tcp_server_callback) in that release.
CALLBACK_SOURCE_SHA256 = "9b8492fb23e3011b788996c705a784b13117e67a64b0ec2e4cfe2c1e7a6e62a4"


def test_rospy_is_the_release_the_patch_was_written_for():
    assert importlib.metadata.version("rospy") == ROSPY_VERSION


def test_the_patched_callback_is_unchanged():
    source = inspect.getsource(tcpros_base.TCPROSServer._tcp_server_callback)
    assert hashlib.sha256(source.encode()).hexdigest() == CALLBACK_SOURCE_SHA256
    assert "read_ros_handshake_header(sock" in source


def test_the_server_binds_the_callback_when_it_starts():
    # Patching the class before init_node works only because the bound method is looked up
    # when the TCP server starts, not when the module is imported.
    source = inspect.getsource(tcpros_base.TCPROSServer.start_server)
    assert "TCPServer(self._tcp_server_callback, self.port)" in source
