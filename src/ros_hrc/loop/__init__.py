"""The loop room (DESIGN §2, §8): the episode coordinator, its runner and what it displays.
No ROS, no sockets, no PyBullet. The foundations it stands on (the task registry
:mod:`ros_hrc.tasks`, :mod:`ros_hrc.settings`, :mod:`ros_hrc.streams`, :mod:`ros_hrc.models`)
live on lower floors (docs/architecture.md).

  ros_hrc.loop.effects      what goes in and out of it: answers, requests, calls, notices,
                            a step's report
  ros_hrc.loop.coordinator  the Sans-I/O episode coordinator: the MDP's seat, the loop's
                            phase, and the routing of events to its parts:
  ros_hrc.loop.step         one step: observe -> decide -> act, its report and its waits
  ros_hrc.loop.resets       epochs and resets: drain, reset, start; joining, retrying
  ros_hrc.loop.schedule     the episode schedule: which episode a reset starts, its end
  ros_hrc.loop.sequence     a sequence of tasks: who plays each, its outcome, its end
  ros_hrc.loop.outbox       where the parts put their effects and calls
  ros_hrc.loop.config       the coordinator's configuration and the loop's default waits
  ros_hrc.loop.runner       runs a coordinator's effects against four interfaces, in threads
  ros_hrc.loop.display      the step's block and caption text, from a step's fields

Nothing is imported here, so each module stays cheap to import.
"""
