"""tools/type_beliefs.py: the type belief of a study's pomdp_types episodes, replayed from
steps.csv on the shipped seed model of types."""
import sys
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[3]
def test_a_replayed_episode_is_the_exact_belief_step_by_step(tmp_path):
    sys.path.insert(0, str(ROOT / "tools"))
    try:
        import type_beliefs
    finally:
        sys.path.remove(str(ROOT / "tools"))
    from ros_hrc.models import load_robot_model
    from ros_hrc.pomdp.belief import update
    from ros_hrc.pomdp.typed import TypeLayout
    model = load_robot_model("robot_types", "seed")
    layout = TypeLayout.of(model)
    steps = [{"observation": "O7", "robot_action": "rIdle"},
             {"observation": "O7", "robot_action": "rStop_all"},
             {"observation": "O11", "robot_action": "rIdle"}]
    got = type_beliefs.episode_type_beliefs(model, layout, steps)
    b = model.initial_belief
    previous = model.index("action", "rIdle")          # the robot process's first action
    for row, replayed in zip(steps, got):
        b, _ = update(model, b, previous, model.index("observation", row["observation"]))
        previous = model.index("action", row["robot_action"])
        assert np.allclose(replayed, layout.type_marginal(b))
