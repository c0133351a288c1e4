"""The caption of the step being played, as the world's node hands it to PyBullet's window and
to /hrc/caption (nodes.world_node.CaptionBoard around loop.display.StepCaption): every
caption is one step's, whole, the same in both places, and never goes back a step. No ROS
master: the board is given plain callables for the window and the topic."""
from types import SimpleNamespace

from ros_hrc.nodes.world_node import CaptionBoard

STATES = ("S0", "S1", "S2", "S3", "S4", "S5", "S6")

#: What each step's agents do: world services, what the world says, the loop's report.
STEPS = {
    0: dict(human=("attempt_grasp", "missed the object by 0.10 m"),
            robot=("grasp", "cannot grasp: the object is out of reach"),
            report=dict(human_action="graspAttempt", human_state="failed_to_grasp",
                        robot_action="rGrasp_obj", robot_result="cannot grasp: out of reach")),
    1: dict(human=("walk_away", "walked 1.5 m away from the belt"),
            robot=("point_to_obj", "pointed at the object"),
            report=dict(human_action="walkAway", human_state="recovery",
                        robot_action="rPoint_obj", robot_result="pointed")),
}
#: Words that only a caption of that step may hold.
WORDS = {0: ("tries to grasp", "missed the object", "reaches for the object", "graspAttempt",
             "rGrasp_obj", "cannot grasp"),
         1: ("walks away", "walked 1.5 m", "points at the object", "walkAway", "rPoint_obj",
             "pointed")}


def report(step):
    return SimpleNamespace(step=step, episode=1, observation_bits=3, robot_observation="O3",
                           robot_state="S2", belief_states=STATES,
                           belief=(0.1, 0.1, 0.5, 0.1, 0.1, 0.05, 0.05), object_holder="none",
                           episode_over=False, end_reason="", fault="", **STEPS[step]["report"])


def drive(board, order):
    """Play ``order``: (step, "human"|"robot") runs that agent's action; (step, "report")
    delivers the loop's report of the step."""
    for step, what in order:
        if what == "report":
            board.step_done(report(step))
        else:
            action, said = STEPS[step][what]
            board.action_started(what, action)
            board.action_finished(what, action, True, said)


def captions_of(order):
    shown, published = [], []
    board = CaptionBoard(lambda lines: shown.append(list(lines)), published.append)
    board.action_finished("world", "reset", True, "reset")
    drive(board, order)
    assert ["\n".join(lines) for lines in shown] == published   # one text, read the same way
    return shown


def step_of(lines):
    """The step a caption names on its first line (``episode 1, step 3: playing``)."""
    first = lines[0]
    return int(first.split("step ", 1)[1].split(":", 1)[0]) if "step " in first and ":" in first else None


def check_whole(captions):
    named = []
    for lines in captions:
        step = step_of(lines)
        if step is None:   # the reset's caption
            assert len(lines) == 1 and "reset" in lines[0]
            continue
        other = 1 - step
        text = "\n".join(lines)
        assert not any(word in text for word in WORDS[other]), f"step {step}'s caption: {lines}"
        named.append(step)
    assert named == sorted(named), f"the caption went back a step: {named}"
    return named


def test_each_caption_is_one_step_s_in_the_usual_order():
    captions = captions_of([(0, "human"), (0, "robot"), (0, "report"),
                            (1, "human"), (1, "robot"), (1, "report")])
    named = check_whole(captions)
    assert named[0] == 0 and named[-1] == 1
    assert captions[-1][0] == "episode 1, step 1: done"


def test_a_late_report_leaves_the_caption_on_the_step_being_played():
    """Step 0's report reaches the world after step 1's human action has ended: the caption
    stays on step 1, which keeps what its human did (before, it went back to step 0's report,
    then said step 1's human was "about to act" while the robot pointed)."""
    captions = captions_of([(0, "human"), (0, "robot"), (1, "human"), (0, "report"),
                            (1, "robot"), (1, "report")])
    check_whole(captions)
    pointing = next(lines for lines in captions if "robot: points at the object ..." in lines)
    assert pointing[:2] == ["episode 1, step 1: playing",
                            "human: walks away -> walked 1.5 m away from the belt"]
    assert pointing[3].startswith("before this step: P(human needs help) = 0.75")
    assert captions[-1][0] == "episode 1, step 1: done"


def test_the_caption_is_handed_over_whole_once_per_change():
    shown = []
    board = CaptionBoard(lambda lines: shown.append(list(lines)), None)
    board.action_finished("world", "reset", True, "reset")
    board.action_started("human", "idle")
    board.action_started("human", "idle")   # the same caption again: nothing to show
    assert len(shown) == 2 and shown[-1] == board.lines()
