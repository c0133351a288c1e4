"""ros_hrc: human-robot collaboration with an MDP human, a POMDP robot and a PyBullet world.

Rooms (kept apart; the first three import without ROS):
  ros_hrc.pomdp  POMDP toolkit: model, parsers, beliefs, solvers (numpy/scipy only)
  ros_hrc.world  the PyBullet scene and its actions and predicates (PyBullet only)
  ros_hrc.link   the websocket protocol and transports (websockets only)
  ros_hrc.nodes  rospy nodes gluing the three together (the only code that imports rospy)
"""
