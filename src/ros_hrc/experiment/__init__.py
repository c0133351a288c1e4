"""Experiments: the grid of human models x robot policies x seeds x episodes, and its results.

  ros_hrc.experiment.results  rows, the CSV store an interrupted run resumes from,
                              confidence intervals, summary tables and plots: pure Python,
                              no ROS, no PyBullet
  ros_hrc.experiment.runner   runs the grid through the real stack

Nothing is imported here, so ``import ros_hrc.experiment.results`` pulls in no runner (and no ROS).
"""
