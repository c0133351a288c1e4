"""The seed's models as shipped in models/: what the manual prints, what we completed, and
the numbers the manual reports (Figure 3.9's 212.34, the tired and beginner runs)."""
from pathlib import Path

import numpy as np
import pytest

from ros_hrc.pomdp import cassandra, io, pomdpx

ROOT = Path(__file__).resolve().parents[3]
HUMAN = ROOT / "models" / "human"
ROBOT = ROOT / "models" / "robot"
STATES = ["task_assigned", "success", "failed_to_grasp", "no_attention", "evaluating", "tired",
          "recovery", "warningTheRobot"]
ACTIONS = ["graspAttempt", "lookAround", "idle", "walkAway", "warnRobot"]
SCENARIOS = ["humanModel", "expert", "beginner", "tired", "distracted"]
SEED_CI = (212.202, 212.478)          # Figure 3.9: pomdpsim --simLen 100 --simNum 1000


def human(name: str):
    return pomdpx.load(HUMAN / f"{name}.pomdpx")


def optimal_policy(model, sweeps: int = 3000):
    """Value iteration on the MDP (kept here so this check does not depend on the solvers)."""
    T, r = model.dense_T, model.R_sa
    V = np.zeros(model.n_states)
    for _ in range(sweeps):
        Q = r + model.discount * T @ V
        V = Q.max(axis=0)
    return Q.argmax(axis=0), V


def expected_return(model, policy, steps: int = 100) -> float:
    """Exact expected discounted reward of ``steps`` steps from the initial belief."""
    idx = np.arange(model.n_states)
    P, r = model.dense_T[policy, idx], model.R_sa[policy, idx]
    b, total = model.initial_belief.copy(), 0.0
    for t in range(steps):
        total += model.discount ** t * b @ r
        b = b @ P
    return total


def step_reward(model, action: str, s: str, s2: str) -> float:
    return model.R[model.actions.index(action)][model.states.index(s), model.states.index(s2)]


def prob(model, action: str, s: str, s2: str) -> float:
    return model.T[model.actions.index(action)][model.states.index(s), model.states.index(s2)]


# -- every human scenario ---------------------------------------------------------------------------
@pytest.mark.parametrize("name", SCENARIOS)
def test_each_human_model_is_a_valid_8_state_5_action_mdp_as_in_figure_3_5(name):
    m = human(name)
    m.validate()
    assert m.states == STATES and m.actions == ACTIONS
    assert m.fully_observable and m.observations == STATES
    assert m.discount == 0.98
    assert np.array_equal(m.initial_belief, np.eye(8)[0])              # Figure 3.6
    info = m.meta["pomdpx"]
    assert info["state_variables"][0]["prev"] == "state_0"
    assert info["state_variables"][0]["curr"] == "state_1"
    assert info["action_variable"] == "action_agent" and info["reward_variables"] == ["reward_agent"]


def test_the_scenarios_behave_differently():
    first_actions = {name: ACTIONS[optimal_policy(human(name))[0][0]] for name in SCENARIOS}
    assert first_actions == {"humanModel": "warnRobot", "expert": "graspAttempt",
                             "beginner": "idle", "tired": "idle", "distracted": "lookAround"}


# -- humanModel: Figures 3.5-3.9 ---------------------------------------------------------------------
def test_human_model_uses_the_printed_tables():
    m = human("humanModel")
    grasp = [[0.1, 0.45, 0.45, 0, 0, 0, 0, 0], [0, 1, 0, 0, 0, 0, 0, 0], [0, 0.6, 0.4, 0, 0, 0, 0, 0],
             [0, 0.4, 0.6, 0, 0, 0, 0, 0], [0, 0.6, 0.3, 0, 0.1, 0, 0, 0], [0, 0, 0, 0, 0, 1, 0, 0],
             [0, 0, 0, 0, 0, 0, 1, 0], [0, 0.5, 0.5, 0, 0, 0, 0, 0]]            # Figure 3.7
    assert np.array_equal(m.dense_T[0], grasp)
    idle = np.eye(8)
    idle[0] = [0.1, 0, 0, 0, 0, 0.9, 0, 0]                                  # Figure 3.14
    assert np.array_equal(m.dense_T[2], idle)
    assert np.array_equal(m.dense_T[3], np.eye(8))                          # Figure 3.14
    for action, target in (("lookAround", "no_attention"), ("warnRobot", "warningTheRobot")):
        t = m.dense_T[ACTIONS.index(action)]
        assert t[0, STATES.index(target)] == 1
        assert np.array_equal(t[1:], np.eye(8)[1:])                         # others stay


def test_human_model_rewards_are_figure_3_8_on_the_next_state():
    m = human("humanModel")
    printed = {("warnRobot", "warningTheRobot"): 4.6, ("graspAttempt", "success"): 5,
               ("idle", "evaluating"): 4.9, ("lookAround", "no_attention"): 2,
               ("walkAway", "recovery"): 4}
    for a, action in enumerate(ACTIONS):
        for j, state in enumerate(STATES):
            assert np.all(m.R[a].toarray()[:, j] == printed.get((action, state), 0))


def test_human_model_reproduces_figure_3_9():
    m = human("humanModel")
    policy, _ = optimal_policy(m)
    exact = expected_return(m, policy)
    assert SEED_CI[0] < exact < SEED_CI[1], exact              # 212.4155
    # 1000 simulated runs of 100 steps, as pomdpsim: the 95 % intervals overlap.
    rng = np.random.default_rng(2024)
    runs = 1000
    s = np.zeros(runs, dtype=int)
    total = np.zeros(runs)
    cumulative = np.cumsum(m.dense_T, axis=2)
    R = np.stack([r.toarray() for r in m.R])
    for t in range(100):
        a = policy[s]
        s2 = np.minimum((cumulative[a, s] < rng.random(runs)[:, None]).sum(axis=1), 7)
        total += m.discount ** t * R[a, s, s2]
        s = s2
    half = 1.96 * total.std(ddof=1) / np.sqrt(runs)
    low, high = total.mean() - half, total.mean() + half
    assert low < SEED_CI[1] and high > SEED_CI[0], (low, high)


# -- the tired human: Figures 3.11-3.14 ------------------------------------------------------------------
def test_tired_human_follows_the_seeds_run():
    m = human("tired")
    assert prob(m, "idle", "task_assigned", "tired") == 0.9                 # Figure 3.14
    assert prob(m, "walkAway", "tired", "recovery") == 1
    policy, _ = optimal_policy(m)
    chosen = {s: ACTIONS[policy[i]] for i, s in enumerate(STATES)}
    assert (chosen["task_assigned"], chosen["tired"], chosen["recovery"]) == ("idle", "walkAway", "idle")
    # Figures 3.11-3.13: rewards 0, 17, 17; accumulated discounted 0, 16.66, 32.9868.
    path = [("idle", "task_assigned", "tired"), ("walkAway", "tired", "recovery"),
            ("idle", "recovery", "recovery")]
    rewards = [step_reward(m, *step) for step in path]
    assert rewards == [0, 17, 17]
    discounted = np.cumsum([0.98 ** t * r for t, r in enumerate(rewards)])
    assert np.allclose(discounted, [0, 16.66, 32.9868])


# -- the beginner: Figures 3.15-3.16 -----------------------------------------------------------------
def test_beginner_reproduces_the_seeds_autonomous_run():
    m = human("beginner")
    path = [("idle", "task_assigned", "evaluating"), ("idle", "evaluating", "evaluating"),
            ("warnRobot", "evaluating", "evaluating"), ("idle", "evaluating", "evaluating"),
            ("idle", "evaluating", "evaluating"), ("graspAttempt", "evaluating", "evaluating"),
            ("graspAttempt", "evaluating", "success")]
    assert all(prob(m, *step) > 0 for step in path)                         # every step can happen
    rewards = [step_reward(m, *step) for step in path]
    assert rewards == [9, 9, 0, 9, 9, 0, 4.9]
    discounted = np.cumsum([0.98 ** t * r for t, r in enumerate(rewards)])
    assert np.allclose(discounted, [9, 17.82, 17.82, 26.2907, 34.592, 34.592, 38.9327], atol=5e-5)


def test_expert_grasps_at_once_and_distracted_loses_attention():
    expert, distracted = human("expert"), human("distracted")
    assert prob(expert, "graspAttempt", "task_assigned", "success") >= 0.9
    for s in ("task_assigned", "failed_to_grasp", "evaluating", "warningTheRobot"):
        assert prob(distracted, "graspAttempt", s, "no_attention") >= 0.3
    assert prob(expert, "idle", "task_assigned", "tired") == 0                # never tires


# -- the robot: Figures 3.17-3.20 ----------------------------------------------------------------------
def test_robot_pomdp_and_pomdpx_are_the_same_model():
    a = cassandra.load(ROBOT / "robot.pomdp")
    b = pomdpx.load(ROBOT / "robot.pomdpx")
    assert io.differences(a, b) == []
    # and the .pomdpx is exactly what `hrc_pomdp convert` writes from the .pomdp
    assert pomdpx.dump(a) == (ROBOT / "robot.pomdpx").read_text()


def test_robot_model_has_the_seeds_sizes_names_and_start():
    m = cassandra.load(ROBOT / "robot.pomdp")
    assert m.states == [f"S{i}" for i in range(7)]
    assert m.actions == ["rIdle", "rPoint_obj", "rGrasp_obj", "rStop_all"]
    assert m.observations == [f"O{b}" for b in (0, 1, 2, 3, 7, 10, 11, 16, 17, 18, 19, 32, 33, 34, 35)]
    assert m.discount == 0.9 and not m.minimise and not m.fully_observable
    assert np.array_equal(m.initial_belief, np.eye(7)[0])


def test_robot_transitions_use_the_printed_rows():
    m = cassandra.load(ROBOT / "robot.pomdp")
    assert np.array_equal(m.dense_T[0][0], [0.3, 0.4, 0.15, 0, 0.15, 0, 0])   # Figure 3.18
    assert np.array_equal(m.dense_T[0][4], [0, 0.3, 0, 0, 0.3, 0.4, 0])
    assert np.array_equal(m.dense_T[1][5], [0, 0.5, 0.15, 0, 0.025, 0.3, 0.025])
    assert np.array_equal(m.dense_T[2][0], [1, 0, 0, 0, 0, 0, 0])
    assert m.dense_T[2][3, 1] > 0.5 and m.dense_T[3][6, 1] > 0                  # completed


def test_robot_observations_are_figure_3_19_aligned_and_normalised():
    m = cassandra.load(ROBOT / "robot.pomdp")
    O = m.dense_O[0]
    col = {name: i for i, name in enumerate(m.observations)}
    assert O[0, col["O35"]] == 0.9 and O[1, col["O11"]] == 0.8               # 14-column rows
    assert np.allclose(O[6, [col[o] for o in ("O16", "O17", "O18", "O19")]], [0.05, 0.15, 0.1, 0.7])
    assert O[5, col["O0"]] == 0.3 and O[5, col["O2"]] == 0.7                  # the 15-column row
    printed_s3 = np.array([0, 0.1, 0.15, 0.05, 0.05, 0.05, 0.1, 0, 0, 0, 0, 0.1, 0.25, 0.05, 0.15])
    assert np.allclose(O[3], printed_s3 / 1.05)                               # summed to 1.05
    assert all(np.array_equal(m.dense_O[a], O) for a in range(4))


def test_robot_rewards_encourage_helping_and_punish_idling():
    m = cassandra.load(ROBOT / "robot.pomdp")
    assert step_reward(m, "rGrasp_obj", "S3", "S1") > 10
    assert step_reward(m, "rPoint_obj", "S5", "S1") > 10
    assert step_reward(m, "rStop_all", "S6", "S1") > 10
    for s in ("S3", "S5", "S6"):
        assert step_reward(m, "rIdle", s, s) < 0
    assert -5 <= step_reward(m, "rPoint_obj", "S3", "S3") < 0               # slight punishment
    assert -5 <= step_reward(m, "rGrasp_obj", "S5", "S5") < 0
    policy, _ = optimal_policy(m)              # as if the robot saw the state
    assert [m.actions[policy[i]] for i in (3, 5, 6)] == ["rGrasp_obj", "rPoint_obj", "rStop_all"]
