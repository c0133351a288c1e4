"""The seed's task, under its old name: ``ros_hrc.loop.task`` is :mod:`ros_hrc.tasks.seed`.

The loop itself reads the task it runs from a :class:`~ros_hrc.tasks.definition.Task`
(:mod:`ros_hrc.tasks`); this module keeps the seed's names importable where they were.
"""
from ros_hrc.tasks.seed import *  # noqa: F401,F403
from ros_hrc.tasks.seed import (_BIT_PRIORITY, EVALUATING_MAY_NEED_HELP,  # noqa: F401
                                EVALUATING_NEEDS_HELP, RobotStateTracker)
