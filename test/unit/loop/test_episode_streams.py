"""Independent episodes at the process level (issue #21): the human MDP process, the robot
process and the world reseed from (seed, episode, role) at each episode's reset, and the
coordinator plays the study's episode numbers (a schedule), so no two episodes share a stream
and one (seed, episode) replays alone exactly.

Before: despot_mdp seeded episode e with ``seed + e - 1`` (so (seed 1, episode e) replayed
(seed 0, episode e + 1)), the planner and the world were seeded once per process (an
episode's draws depended on the episodes before it), and the coordinator numbered episodes
1, 2, 3 ... whatever the cell asked for."""
from types import SimpleNamespace
from typing import List

import pytest

from ros_hrc.link.protocol import Decision, Observation, Reset
from ros_hrc.loop.coordinator import EPISODE_OVER, CoordinatorConfig
from ros_hrc.loop.effects import Fault, MdpReset, ResetDone, ResetPlanner, ResetWorld
from ros_hrc.models import load_human_model, load_robot_model
from ros_hrc.streams import EpisodeSchedule
from ros_hrc.pomdp.despot import DespotConfig, DespotPlanner
from ros_hrc.processes.despot_mdp import MdpProcess
from ros_hrc.processes.despot_pomdp import PomdpProcess, RobotAgent
from ros_hrc.agents.human import HumanAgent, HumanAgentConfig
from ros_hrc.agents.robots import ExplorePlanner

from loop_fakes import Driver, of, one

STEPS = 25


@pytest.fixture(scope="module")
def human_model():
    return load_human_model("beginner")


@pytest.fixture(scope="module")
def robot_model():
    return load_robot_model("robot")


def human_process(model, seed: int) -> MdpProcess:
    agent = HumanAgent(model, HumanAgentConfig(choice="random", seed=seed))
    args = SimpleNamespace(mode="auto", seed=seed, step_delay=0.0, reply_timeout=5.0)
    return MdpProcess(agent, client=None, args=args, out=_Sink())


class _Sink:
    def write(self, text: str) -> int:
        return len(text)

    def flush(self) -> None:
        pass


def human_episode(process: MdpProcess, episode: int) -> List[str]:
    """The human's actions and states along an episode the coordinator starts with a reset
    naming ``episode`` (as despot_mdp steps them, without the link)."""
    process.start_episode(Reset(reason="test", episode=episode, epoch=episode + 1))
    agent, trace = process.agent, [process.agent.state_name]
    for _ in range(STEPS):
        result = agent.advance(agent.choose_action())
        trace += [result.action, result.state]
    return trace


def test_the_human_of_seed_1_episode_e_is_not_the_human_of_seed_0_episode_e_plus_1(human_model):
    zero, one_ = human_process(human_model, 0), human_process(human_model, 1)
    pairs = [(human_episode(one_, e), human_episode(zero, e + 1)) for e in range(8)]
    # Before, every pair was the same human (seed + episode - 1 both times).
    assert sum(a == b for a, b in pairs) < len(pairs) // 2


def test_no_two_episodes_of_the_human_share_a_stream(human_model):
    process = human_process(human_model, 0)
    traces = [tuple(human_episode(process, e)) for e in range(10)]
    assert len(set(traces)) > len(traces) // 2
    # Episode 0 is an episode of its own (the reset's number 0 is not "no number").
    assert traces[0] != tuple(human_episode(human_process(human_model, 0), 1))


def test_one_human_episode_replays_alone_exactly(human_model):
    in_grid = human_process(human_model, 4)
    for e in (0, 1, 2):
        human_episode(in_grid, e)
    third = human_episode(in_grid, 3)
    assert human_episode(human_process(human_model, 4), 3) == third


def test_a_reset_without_a_number_starts_the_next_episode(human_model):
    process = human_process(human_model, 0)
    process.start_episode(Reset(reason="test", episode=0, epoch=1))
    process.start_episode(Reset(reason="by hand", epoch=2))
    assert process.episode == 1


OBSERVATIONS = ("O35", "O7", "O7", "O35", "O2", "O0", "O3", "O19", "O7", "O11")


def robot_episode(process: PomdpProcess, episode: int) -> List[str]:
    """The robot's actions along the observations, in an episode reset as ``episode``."""
    epoch = 100 + episode
    process.on_reset(Reset(reason="test", episode=episode, epoch=epoch), peer=None)
    actions = []
    for step, name in enumerate(OBSERVATIONS):
        answer = process.on_observation(Observation(step=step, observation=name, bits=0,
                                                    state="S0", epoch=epoch, id=step + 1),
                                        peer=None)
        assert isinstance(answer, Decision), answer
        actions.append(answer.action)
    return actions


def explore_process(model, seed: int) -> PomdpProcess:
    return PomdpProcess(RobotAgent(model, ExplorePlanner(model, seed=seed), seed=seed))


def despot_process(model, seed: int) -> PomdpProcess:
    config = DespotConfig(scenarios=100, time_per_step=float("inf"), max_trials=20)
    return PomdpProcess(RobotAgent(model, DespotPlanner(model, config, seed=seed), seed=seed))


def test_the_exploring_robot_draws_a_stream_per_episode(robot_model):
    zero, one_ = explore_process(robot_model, 0), explore_process(robot_model, 1)
    runs = [tuple(robot_episode(zero, e)) for e in range(6)]
    assert len(set(runs)) == len(runs)
    assert robot_episode(one_, 2) != robot_episode(zero, 3)
    # Replayed alone, after nothing else: the same actions.
    assert robot_episode(explore_process(robot_model, 0), 4) == list(runs[4])


def test_one_despot_episode_replays_alone_exactly(robot_model):
    in_grid = despot_process(robot_model, 7)
    for e in (0, 1):
        robot_episode(in_grid, e)
    third = robot_episode(in_grid, 2)
    assert robot_episode(despot_process(robot_model, 7), 2) == third
    # Before, the planner's stream ran on across episodes: its draws in episode 2 depended on
    # episodes 0 and 1. Now each reset restarts it as the episode's own.
    planner = in_grid.agent.planner
    robot_episode(in_grid, 5)
    after_five = planner.rng.bit_generator.state
    robot_episode(despot_process(robot_model, 7), 5)
    fresh = despot_process(robot_model, 7)
    robot_episode(fresh, 5)
    assert fresh.agent.planner.rng.bit_generator.state == after_five


# -- the coordinator plays the study's episode numbers ------------------------------------------

def _schedule(text: str, **more) -> CoordinatorConfig:
    return CoordinatorConfig(max_steps=2, on_episode_end="reset",
                             episodes=EpisodeSchedule.parse(text), **more)


def _end_episode(driver: Driver) -> list:
    """Play the episode's two steps (the step limit); the effects of the last."""
    driver.play_step()
    return driver.play_step().effects


def test_a_cell_s_episodes_are_played_by_their_numbers():
    driver = Driver(_schedule("5,7"))
    effects = driver.connect()
    assert one(effects, ResetWorld, interrupt=False).episode == 5
    assert one(effects, ResetPlanner).episode == 5
    out = driver.finish_reset(effects)
    assert one(out, MdpReset).episode == 5 and driver.c.episode == 5
    out = _end_episode(driver)
    assert one(out, ResetPlanner).episode == 7 and one(out, ResetWorld, interrupt=False).episode == 7
    assert one(driver.finish_reset(out), MdpReset).episode == 7
    out = _end_episode(driver)
    # The last episode of the schedule is over: no reset starts another.
    assert not of(out, ResetPlanner) and driver.c.phase == EPISODE_OVER
    refused = one(driver.reset(), ResetDone)
    assert not refused.success and "all played" in refused.message


def test_an_episode_cut_short_is_played_again_under_its_number():
    driver = Driver(_schedule("3-4"))
    driver.ready()
    assert driver.c.episode == 3
    played = driver.play_step(until="observe")
    # The world fails the step: the loop resets, into episode 3 again (whole, its streams).
    out = driver.answer(played.calls[-1], Fault("world gone"))
    assert one(out, ResetPlanner).episode == 3
    assert one(driver.finish_reset(out), MdpReset).episode == 3
    out = _end_episode(driver)
    assert one(out, ResetPlanner).episode == 4


def test_live_episodes_are_numbered_1_2_3_as_before():
    driver = Driver(CoordinatorConfig(max_steps=1, on_episode_end="reset"))
    assert one(driver.connect(), ResetPlanner).episode == 1
    driver.finish_reset(driver.log)
    out = driver.play_step().effects
    assert one(out, ResetPlanner).episode == 2
    driver.finish_reset(out)
    # A reset asked for mid-episode starts the next number, as it always did.
    assert one(driver.reset(), ResetPlanner).episode == 3


# -- the world ---------------------------------------------------------------------------------

def _misses(world, episode: int) -> str:
    world.reseed(episode)
    world.run("world", "reset")
    return world.run("human", "attempt_grasp").message


def test_the_world_draws_a_stream_per_episode_and_replays_one_alone():
    from ros_hrc.world import World, WorldConfig
    with World(WorldConfig(seed=3)) as world:
        misses = [_misses(world, e) for e in range(1, 6)]
    assert len(set(misses)) > 1, misses
    with World(WorldConfig(seed=3)) as alone:
        assert _misses(alone, 4) == misses[3]
