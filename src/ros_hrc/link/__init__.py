"""The websocket link between the solver processes and the ROS nodes (DESIGN §2, §6).

  ros_hrc.link.protocol   messages (protocol version 2: every one with an epoch / id /
                          reply_to envelope), encode / decode / validation, reply matching
                          (is_reply_to) and DispatchTable: pure, no I/O (Sans-I/O)
  ros_hrc.link.transport  MessageServer (sends never block it: a bounded outbox per peer)
                          and MessageClient (request() by correlation id): the only module
                          that imports a websocket library

Nothing is imported here, so ``import ros_hrc.link.protocol`` stays free of websockets.
docs/protocol.md describes the protocol.
"""
