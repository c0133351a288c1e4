"""A reset without an episode number starts the next one, and after the largest number a
stream takes the solvers start again from 0 rather than fail (the launched fuzz test sent
a reset of episode 2**32 - 1 and then one without a number: despot_pomdp's handler raised)."""
import io

from ros_hrc import tasks
from ros_hrc.agents.human import HumanAgent
from ros_hrc.link.protocol import Ack, Reset
from ros_hrc.models import load_human_model, load_robot_model
from ros_hrc.processes import despot_mdp, despot_pomdp
from ros_hrc.streams import MAX_EPISODE, next_episode

SEED = tasks.get("seed")


def test_next_episode_wraps_after_the_largest():
    assert [next_episode(None), next_episode(0), next_episode(41)] == [0, 1, 42]
    assert next_episode(MAX_EPISODE) == 0


def test_the_robot_process_takes_a_reset_without_a_number_after_the_largest():
    args = despot_pomdp.build_parser().parse_args(["--time-per-step", "0", "--max-trials", "5"])
    model = load_robot_model(args.robot_model, SEED)
    agent = despot_pomdp.RobotAgent(model, despot_pomdp.build_planner(model, args))
    process = despot_pomdp.PomdpProcess(agent)
    assert isinstance(process.on_reset(Reset(episode=MAX_EPISODE, epoch=1), None), Ack)
    assert isinstance(process.on_reset(Reset(epoch=2), None), Ack)
    assert process.agent.episode == 0


def test_the_human_process_takes_a_reset_without_a_number_after_the_largest():
    args = despot_mdp.build_parser().parse_args([])
    agent = HumanAgent(load_human_model(args.human_model, SEED))
    process = despot_mdp.MdpProcess(agent, client=None, args=args, out=io.StringIO())
    process.start_episode(Reset(episode=MAX_EPISODE, epoch=1))
    process.start_episode(Reset(epoch=2))
    assert process.episode == 0
