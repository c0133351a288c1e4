"""planner:=my_planner: the action of the best immediate reward under the belief."""
from ros_hrc.pomdp.planner import BeliefPlanner, PlannerStats


class GreedyPlanner(BeliefPlanner):
    """argmax_a Σ_s b(s) R(s, a), one step ahead and no further; with probability ``explore``
    a uniformly random action instead, drawn from the episode's stream (``self.rng``)."""

    plans_on_model = True          # it decides on the robot model's rewards
    options = {"explore": 0.0}     # a library policy may set it

    def __init__(self, model, seed=None, explore=0.0):
        if not 0.0 <= explore <= 1.0:
            raise ValueError(f"explore must be from 0 to 1, got {explore}")
        super().__init__(model, seed)
        self.explore = explore

    def act(self):
        values = self.model.R_sa @ self.belief
        self.last_stats = PlannerStats(action_values=dict(enumerate(values.tolist())))
        if self.rng.random() < self.explore:
            return int(self.rng.integers(self.model.n_actions))
        return int(values.argmax())
