"""What the robot process tells of a task of a sequence (issue #41, newcomer item 7): every
decision names the policy that decides the task (so the task's first step block shows the
selector's choice when the task starts, not only its end), and a reactive policy's report
names what the reactive robot acts by (the reactive MDP's file), not an empty robot_model."""
from ros_hrc import tasks
from ros_hrc.link.protocol import Decision, Observation, Reset, TaskEnd, TaskReport
from ros_hrc.loop.effects import Decision as LoopDecision
from ros_hrc.models import load_robot_model
from ros_hrc.processes import despot_pomdp

FABRIC = tasks.get("fabric")
SEED = tasks.get("seed")


def robot_process(task, *words):
    args = despot_pomdp.build_parser().parse_args(
        ["--task", task.name, "--time-per-step", "0", "--max-trials", "20", *words])
    model = load_robot_model(args.robot_model, task)
    sequence = despot_pomdp.build_sequence_robot(task, model,
                                                 despot_pomdp.build_planner(model, args), args)
    return despot_pomdp.PomdpProcess(next(iter(sequence.agents.values())), sequence)


def play_task(process, index=1, epoch=5):
    """Task ``index``'s reset, one observation, its end: (the decision, the task's report)."""
    process.on_reset(Reset(episode=index, task_index=index, true_type="tired", epoch=epoch),
                     None)
    model = process.agent.model
    decision = process.on_observation(Observation(step=0, observation=model.observations[0],
                                                  bits=1, state=model.states[0],
                                                  epoch=epoch, elapsed=0.0), None)
    report = process.on_task_end(TaskEnd(task_index=index, outcome="success", warnings=0,
                                         preemptions=0, steps=1, duration=3.0, utility=0.9,
                                         epoch=epoch, id=7), None)
    return decision, report


def test_each_decision_of_a_task_names_the_policy_its_selector_chose_at_its_start():
    process = robot_process(FABRIC, "--model", "base", "--selector", "fixed:policy3")
    decision, report = play_task(process)
    assert isinstance(decision, Decision) and decision.policy == "policy3"
    assert LoopDecision.of(decision).policy == "policy3"     # into the step's report
    assert report.policy == "policy3"


def test_a_decision_outside_a_sequence_names_no_policy():
    process = robot_process(SEED)
    process.on_reset(Reset(episode=1, epoch=3), None)
    model = process.agent.model
    decision = process.on_observation(Observation(step=0, observation=model.observations[0],
                                                  bits=1, state=model.states[0], epoch=3),
                                      None)
    assert decision.policy is None


def test_the_library_s_reactive_policy_reports_the_reactive_mdp_it_acts_by():
    process = robot_process(FABRIC, "--model", "base", "--selector", "fixed:reactive")
    _, report = play_task(process)
    assert isinstance(report, TaskReport) and report.policy == "reactive"
    assert report.robot_model.endswith("models/fabric/robot/reactive.pomdpx")


def test_the_launch_s_one_reactive_robot_reports_what_it_acts_by():
    fabric = robot_process(FABRIC, "--model", "base", "--planner", "reactive")
    _, report = play_task(fabric)
    assert report.policy == "reactive"
    assert report.robot_model.endswith("models/fabric/robot/reactive.pomdpx")
    seed = robot_process(SEED, "--planner", "reactive")     # the seed's: rules, no file
    _, report = play_task(seed)
    assert report.robot_model == "reactive (rules)"
