"""The agents' room: what decides for the robot or the human, above the POMDP toolkit and
the task definitions, below the loop and the processes that run them.

  ros_hrc.agents.robots        the baseline robots (reactive, no robot, exploring) as planners
  ros_hrc.agents.human         the human's MDP agent: its state, actions and manual entry
  ros_hrc.agents.policy_table  a robot policy's choices over observation sequences, with beliefs
  ros_hrc.agents.library       a task's policy library (a manifest of robot policies to choose among)

Nothing is imported here, so each module stays cheap to import.
"""
