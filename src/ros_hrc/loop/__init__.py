"""The loop room (DESIGN §2, §8): the settings every entry point shares, model validation
against the task (:mod:`ros_hrc.tasks`) and the episode coordinator. No ROS, no sockets, no
PyBullet.

  ros_hrc.loop.task         the seed task's tables under their old name (ros_hrc.tasks.seed)
  ros_hrc.loop.settings     one source of defaults and checks for every launch argument
  ros_hrc.loop.models       the human and robot models checked against the task's tables
  ros_hrc.loop.coordinator  the Sans-I/O episode coordinator: step, epoch, order, episodes
  ros_hrc.loop.runner       runs a coordinator's effects against four interfaces, in threads

Nothing is imported here, so each module stays cheap to import.
"""
