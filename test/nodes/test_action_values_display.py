"""Why the robot acted, on screen: the step block's ``robot values`` line (hrc_human's
format_step, on a real ros_hrc/Status) and the caption's robot line (status_lines) show the
planner's value of the chosen action against the others, so that a grasp at
P(human needs help) = 0.03 explains itself. A baseline robot sends no values: no line."""
from ros_hrc.loop.display import action_values_text, ranked_action_values, status_lines
from ros_hrc.msg import Status
from ros_hrc.nodes.human_node import format_step

STATES = ["S0", "S1", "S2", "S3", "S4", "S5", "S6"]


def grasp_at_low_need(**over):
    """The authors' case: the robot grasps while it believes the human needs help with 0.03."""
    fields = dict(step=3, episode=1, human_action="idle", human_state="evaluating",
                  observation_bits=3, robot_observation="O3", robot_state="S1",
                  robot_action="rGrasp_obj", belief_states=STATES,
                  belief=[0.97, 0.0, 0.03, 0.0, 0.0, 0.0, 0.0],
                  action_names=["rIdle", "rPoint_obj", "rGrasp_obj", "rStop_all"],
                  action_values=[48.48412, 38.112, 60.03891, 38.112])
    fields.update(over)
    return Status(**fields)


def test_the_step_block_shows_every_action_s_value_best_first_the_chosen_marked():
    block = format_step(grasp_at_low_need()).splitlines()
    assert "robot values      : rGrasp_obj 60.04 (chosen) > rIdle 48.48 > rPoint_obj 38.11 = " \
           "rStop_all 38.11" in block
    # Right under the action it explains, above the belief.
    at = block.index(next(line for line in block if line.startswith("robot values")))
    assert block[at - 1] == "robot action      : rGrasp_obj"
    assert block[at + 1].startswith("robot belief      : S0 0.970")


def test_the_caption_s_robot_line_gives_the_chosen_value_and_the_next_best():
    lines = status_lines(grasp_at_low_need())
    assert lines[2] == ("robot: sees O3 (visible+in_range), does rGrasp_obj "
                        "(value 60.04 vs rIdle 48.48; true state S1)")
    assert lines[3].startswith("P(human needs help) = 0.03")


def test_a_baseline_robot_without_values_gets_no_values_line():
    status = grasp_at_low_need(action_names=[], action_values=[], rule="help")
    assert not any(line.startswith("robot values") for line in format_step(status).splitlines())
    assert status_lines(status)[2] == ("robot: sees O3 (visible+in_range), does rGrasp_obj "
                                       "(true state S1)")


def test_ties_keep_the_model_s_order_and_one_valued_action_has_no_runner_up():
    tied = grasp_at_low_need(robot_action="rIdle", action_names=["rIdle", "rPoint_obj"],
                             action_values=[0.0, 0.0])
    assert ranked_action_values(tied) == [("rIdle", 0.0), ("rPoint_obj", 0.0)]
    assert action_values_text(tied) == "rIdle 0 (chosen) = rPoint_obj 0"
    # DESPOT's numerical slack (a few 1e-7) is no value of its own.
    slack = grasp_at_low_need(robot_action="rIdle", action_names=["rIdle", "rPoint_obj"],
                              action_values=[-1.664e-07, -0.1])
    assert action_values_text(slack) == "rIdle 0 (chosen) > rPoint_obj -0.1"
    alone = grasp_at_low_need(robot_action="rIdle", action_names=["rIdle"],
                              action_values=[-20.0])
    assert "does rIdle (value -20; true state S1)" in status_lines(alone)[2]


def test_many_actions_stay_on_one_readable_line():
    names = [f"rMove_{i}" for i in range(13)]
    many = grasp_at_low_need(robot_action="rMove_12", action_names=names,
                             action_values=[float(i) for i in range(13)])
    text = action_values_text(many)
    assert len(text) <= 80
    assert text.startswith("rMove_12 12 (chosen) > rMove_11 11 > ")
    shown = text.count(" > ") + 1
    assert text.endswith(f" (+{13 - shown} more)")


def test_a_robot_model_of_types_shows_its_belief_over_the_types_under_the_state_belief():
    """Issue #31: the composed model's belief over the human types is printed each step, the
    most likely first, the first five and '...' for the rest; a robot of no types has no line."""
    types = ["humanModel", "distracted", "walker", "slow_steady", "early_warner",
             "confident_novice", "beginner", "tired"]
    belief = [0.32, 0.04, 0.04, 0.01, 0.04, 0.54, 0.005, 0.005]
    block = format_step(grasp_at_low_need(type_names=types, type_belief=belief)).splitlines()
    at = block.index(next(line for line in block if line.startswith("robot types")))
    assert block[at - 1].startswith("robot belief      : S0 0.970")
    assert block[at] == ("robot types       : confident_novice 0.54, humanModel 0.32, "
                         "distracted 0.04, walker 0.04, early_warner 0.04 ...")
    assert not any(line.startswith("robot types")
                   for line in format_step(grasp_at_low_need()).splitlines())
