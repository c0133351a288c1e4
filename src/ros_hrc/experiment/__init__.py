"""Experiments: the grid of human models x robot policies x seeds x episodes, and its results.

  ros_hrc.experiment.rows        the rows: one per episode, one per step, each checked
  ros_hrc.experiment.store       their CSV store, which an interrupted run resumes from
  ros_hrc.experiment.lock        one run at a time on a results directory
  ros_hrc.experiment.statistics  confidence intervals (Wilson, bootstrap percentile), summary tables
  ros_hrc.experiment.plots       the PNG plots
  ros_hrc.experiment.episode     scoring one episode from its steps
  ros_hrc.experiment.paired      the counterfactual: an episode against the human alone
  ros_hrc.experiment.provenance  which streams a fitted robot model was fitted on
  ros_hrc.experiment.zoo         the human models of the study, fit set and held out
  ros_hrc.experiment.stack       what a cell's worker runs; starting and stopping its hrc.launch
  ros_hrc.experiment.arguments   the argument types hrc_experiment and hrc_fit share
  ros_hrc.experiment.grid        the grid planned: its cells, each with the episodes to record
  ros_hrc.experiment.recording   where a run's episodes go: the alone pairs, the progress
  ros_hrc.experiment.attempts    one cell in up to three attempts, locally or on a cluster
  ros_hrc.experiment.pool        the local pool: cells side by side, stopped by SIGINT/SIGTERM
  ros_hrc.experiment.cluster     --cluster: the cells on Ray actors (the option, the driver)
  ros_hrc.experiment.cluster_task  a lane's Ray actor, on its node: one warm stack
  ros_hrc.experiment.ray_node    a Ray node of one's own (--cluster local, tests, benchmark)
  ros_hrc.experiment.cli         hrc_experiment: checks the grid, locks --out, runs the cells
  ros_hrc.experiment.fit         hrc_fit: the robot model fitted from episodes

None of them imports ROS; the worker's node is ``ros_hrc.nodes.experiment_cell``, which imports
from here (never the reverse). Nothing is imported here, so each module stays cheap to import.
"""
