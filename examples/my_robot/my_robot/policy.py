"""hrc_experiment --policies my_robot: my planner on the grid's robot model."""
from ros_hrc.experiment.episode import RobotPolicy

MY_ROBOT = RobotPolicy(planner="my_planner", robot_model=None,
                       doc="the greedy planner on the grid's robot model")
