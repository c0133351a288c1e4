"""The websocket link between the solver processes and the ROS nodes (DESIGN §2, §6).

The protocol, Sans-I/O (pure, no socket; ``ros_hrc.link.protocol`` gathers its public names):

  messages     the message types (protocol version 2: every one with an epoch / id /
               reply_to envelope); each validates itself when built
  validation   what each field may hold, and the Checker every message uses
  refusals     the error codes of an ``error`` and MessageError
  codec        decode / encode: text frames to messages and back
  replies      reply matching (is_reply_to), error replies and the DispatchTable
  token        the launch's link token and the proofs of the hello

The transport, on the one websocket library ``websockets`` (``ros_hrc.link.transport``
gathers its public names); the only modules that import a websocket library:

  session      what both ends share: where a link is, the websocket settings, and the hello
               handshake of one connection (Session)
  server       MessageServer (a thread per connection; refusals; dispatch)
  peer         Peer: one client of a server; its sends only queue (cut off after link_read_timeout unread)
  client       MessageClient: reconnects by itself, request() by correlation id
  inbox        Inbox: what a client received, and its requests in flight matched to their
               answers (Sans-I/O)

Nothing is imported here, so ``import ros_hrc.link.protocol`` stays free of websockets.
docs/protocol.md describes the protocol.
"""
