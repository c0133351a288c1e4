"""Experiments: the grid of human models x robot policies x seeds x episodes, and its results.

  ros_hrc.experiment.rows        the rows: one per episode, one per step, each checked
  ros_hrc.experiment.store       their CSV store, which an interrupted run resumes from
  ros_hrc.experiment.lock        one run at a time on a results directory
  ros_hrc.experiment.statistics  confidence intervals (Wilson, Student's t), summary tables
  ros_hrc.experiment.plots       the PNG plots
  ros_hrc.experiment.episode     scoring one episode from its steps
  ros_hrc.experiment.stack       what a cell's worker runs; starting and stopping its hrc.launch
  ros_hrc.experiment.cli         hrc_experiment: checks the grid, locks --out, runs the cells

None of them imports ROS; the worker's node is ``ros_hrc.nodes.experiment_cell``, which imports
from here (never the reverse). Nothing is imported here, so each module stays cheap to import.
"""
