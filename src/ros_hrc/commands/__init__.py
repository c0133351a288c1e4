"""The package's programs that are neither a node nor a solver process (DESIGN §8: a program
lives beside what runs it, not in a library room):

  ros_hrc.commands.check        hrc_check, hrc.launch's pre-flight: every argument, both models
  ros_hrc.commands.pomdp        hrc_pomdp: inspect, convert, solve a POMDP; a policy's table
  ros_hrc.commands.pomdp_simulate  hrc_pomdp simulate
  ros_hrc.commands.pomdp_common    what hrc_pomdp's subcommands share (options, printing)
  ros_hrc.commands.description  hrc_description: an agent's URDF with its frames prefixed

Nothing is imported here, so each program stays cheap to import.
"""
