"""The websocket link between the solver processes and the ROS nodes (DESIGN §2, §6).

  ros_hrc.link.protocol   messages, encode / decode / validation: pure, no I/O (Sans-I/O)
  ros_hrc.link.transport  MessageServer and MessageClient: the only module that imports a
                          websocket library

Nothing is imported here, so ``import ros_hrc.link.protocol`` stays free of websockets.
docs/protocol.md describes the protocol.
"""
