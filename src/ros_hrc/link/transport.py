"""The websocket I/O of the protocol, in one import: a server that runs in a background thread
and a client that reconnects by itself, both on the one websocket library, ``websockets`` (its
threaded server and client, with its own keepalive and frame-size limit).
:mod:`ros_hrc.link.protocol` does all encoding, validation, reply matching and dispatch; these
modules move its text frames:

  ros_hrc.link.session  what both ends share: where a link is, the websocket settings, and the
                        hello handshake with its link-token proofs (Session)
  ros_hrc.link.server   MessageServer: one thread per connection, refusals, dispatch
  ros_hrc.link.peer     Peer: one client of a server, whose sends only queue (an outbox cut off by time)
  ros_hrc.link.client   MessageClient: reconnects, says hello, request() by correlation id;
                        LinkTimeout, LinkClosed, LinkDropped, ReplyRejected
  ros_hrc.link.inbox    Inbox: what a client received, its requests matched to their answers

Size limits: a message larger than :data:`~ros_hrc.link.protocol.MAX_MESSAGE_BYTES` is refused
by ``encode`` before it is sent, and answered with an ``error`` when received (the connection
stays up). A frame larger than :data:`FRAME_LIMIT_BYTES` is not even read: the receiving end
closes that connection with code 1009 (message too big), which bounds memory; a client then
reconnects.
"""
from ros_hrc.link.client import (LinkClosed, LinkDropped, LinkTimeout, MessageClient,
                                 ReplyRejected, connect_failure)
from ros_hrc.link.peer import OUTBOX_BYTES, READ_TIMEOUT, Peer
from ros_hrc.link.server import Handler, MessageServer, PeerCallback
from ros_hrc.link.session import (CLOSE_GOING_AWAY, CLOSE_REFUSED, CLOSE_TIMEOUT, DEFAULT_HOST,
                                  FRAME_LIMIT_BYTES, HELLO_TIMEOUT, KEEPALIVE_INTERVAL,
                                  KEEPALIVE_TIMEOUT, free_port, link_url)

__all__ = [
    "MessageServer", "Handler", "PeerCallback", "Peer", "MessageClient",
    "LinkTimeout", "LinkClosed", "LinkDropped", "ReplyRejected", "connect_failure",
    "DEFAULT_HOST", "FRAME_LIMIT_BYTES", "CLOSE_TIMEOUT", "CLOSE_REFUSED", "CLOSE_GOING_AWAY",
    "HELLO_TIMEOUT", "KEEPALIVE_INTERVAL", "KEEPALIVE_TIMEOUT", "OUTBOX_BYTES",
    "READ_TIMEOUT", "free_port", "link_url",
]
