"""The selectors (ros_hrc.agents.selectors): the signature code, BPR's belief update and its two
selection rules, FABRIC's variant, forgetting, the bandit, fixed, random and the oracle, on
cases whose numbers are worked out by hand in the comments."""
import math

import numpy as np
import pytest

from ros_hrc import tasks
from ros_hrc.agents.selector_model import HEADER_KEYS, SIGNATURE_CODES, SelectorModel
from ros_hrc.agents.selectors import (
    DEFAULT_FORGETTING, TaskResult, bandit_reward, expected_improvement,
    fabric_scores, fabric_type_posterior, make_selector, probability_of_improvement,
    signature_code, signature_log_likelihood, type_posterior)

HEADER = {key: "test" for key in HEADER_KEYS}


def signature_rows(*rows):
    """Signature rows over the 64 codes from {code: probability} dicts."""
    table = np.zeros((len(rows), SIGNATURE_CODES))
    for i, row in enumerate(rows):
        for code, p in row.items():
            table[i, code] = p
    return table


def model_of(mean, std, rows=None, policies=None, types=None):
    """A SelectorModel with the given types x policies tables; every policy shares the
    signature ``rows`` (types x 64; uniform when None)."""
    mean, std = np.array(mean, float), np.array(std, float)
    n_types, n_policies = mean.shape
    types = types or tuple(f"type{t}" for t in range(n_types))
    policies = policies or tuple(f"policy{p}" for p in range(n_policies))
    rows = np.full((n_types, SIGNATURE_CODES), 1 / SIGNATURE_CODES) if rows is None else rows
    return SelectorModel(task="fabric", policies=policies, types=types, mean=mean, std=std,
                         signature=np.repeat(rows[None], n_policies, axis=0),
                         tasks_per_pair=np.ones_like(mean), header=HEADER)


# -- the signature ----------------------------------------------------------------------------
# FABRIC's codes of their typical steps (hrc_ros/src/policy_selector_bpr/training_sets/
# matcontrol.py at 621cba9 labels its plots' codes): 5 successful, 9 fail, 17 warn, 33 idle,
# 35 looking around and idle. Our bits: visible 1, in_range 2, grasp_attempt 4, taken 8,
# warning 16, idle 32 (64 left the belt, fabric only).
FABRIC_STEPS = [
    (1 + 2 + 4 + 8, 1 + 4),       # grasped, the object taken: detected + grasped successfully
    (1 + 2 + 4, 1 + 8),           # grasped, nothing taken: detected + failed to grasp
    (1 + 2 + 16, 1 + 16),         # warning
    (1 + 2 + 32, 1 + 32),         # idle, looking at the object
    (2 + 32, 1 + 2 + 32),         # idle, looking around
    (1 + 2, 1),                   # at work, looking at the object
    (0, 2),                       # away: not detected, not looking at the object
    (1 + 2 + 8, 1),               # the object held by the robot: no grasp of his
]


@pytest.mark.parametrize("task_name", ["fabric", "seed"])
@pytest.mark.parametrize("bits,code", FABRIC_STEPS)
def test_signature_code_packs_fabric_observables(task_name, bits, code):
    assert signature_code(bits, tasks.get(task_name)) == code


def test_signature_code_ignores_the_belt_and_refuses_bits_outside_the_task():
    fabric, seed = tasks.get("fabric"), tasks.get("seed")
    assert signature_code(64 + 1 + 2 + 32, fabric) == 33          # left the belt: not a code bit
    assert {signature_code(b, fabric) for b in range(128)} <= set(range(64))
    for bits, task in ((128, fabric), (64, seed), (-1, fabric), (1.5, fabric), (True, seed)):
        with pytest.raises(ValueError, match="outside"):
            signature_code(bits, task)


# -- BPR: the belief update --------------------------------------------------------------------
# Two types, one policy. Type A shows code 1 or 33 with 1/2 each, type B code 1 with 0.2 and
# 33 with 0.8. A task with the codes (1, 33): P(σ | A) = 0.5 * 0.5 = 0.25,
# P(σ | B) = 0.2 * 0.8 = 0.16. From the uniform belief: β(A) = 0.25 / 0.41 = 0.6097561,
# β(B) = 0.16 / 0.41 = 0.3902439.
ROWS_AB = signature_rows({1: 0.5, 33: 0.5}, {1: 0.2, 33: 0.8})


def test_bpr_belief_update_by_hand():
    log_likelihood = signature_log_likelihood(ROWS_AB, (1, 33))
    assert np.exp(log_likelihood) == pytest.approx([0.25, 0.16])
    assert type_posterior(np.array([0.5, 0.5]), log_likelihood) == pytest.approx(
        [0.25 / 0.41, 0.16 / 0.41])
    # A code type A never shows rules A out; one no type shows leaves nothing to update.
    assert type_posterior(np.array([0.5, 0.5]), signature_log_likelihood(ROWS_AB, (1, 2))) \
        is None


def test_bpr_selector_updates_its_belief_and_mixes_in_forgetting():
    model = model_of([[0.0], [0.0]], [[1.0], [1.0]], rows=ROWS_AB)
    selector = make_selector("bpr", model.policies, model, seed=0, forgetting=0.1)
    assert selector.belief() == pytest.approx([0.5, 0.5])       # uniform at the first task
    selector.observe(TaskResult("policy0", (1, 33), 0.3))
    # (1 - 0.1) * 0.6097561 + 0.1 / 2 = 0.5987805; (1 - 0.1) * 0.3902439 + 0.05 = 0.4012195
    assert selector.belief() == pytest.approx([0.5987805, 0.4012195])
    assert selector.type_names == ("type0", "type1")
    selector.observe(TaskResult("policy0", (2,), 0.3))          # no type shows code 2
    assert "probability 0 under every type" in selector.note
    assert selector.belief() == pytest.approx([0.9 * 0.5987805 + 0.05, 0.9 * 0.4012195 + 0.05])


# -- BPR: the two selection rules -------------------------------------------------------------
# One type, two policies: policy0 ~ N(0, 0.1), policy1 ~ N(-0.5, 1). The best expected
# utility is Ū = 0 (policy0). U_max = max(μ + 3σ) = max(0.3, 2.5) = 2.5.
# EI (to +inf) of N(μ, σ) over Ū: σ φ(z) + (μ - Ū) P(Z ≥ z), z = (Ū - μ) / σ:
#   policy0: 0.1 φ(0) = 0.1 * 0.3989423 = 0.0398942
#   policy1: φ(0.5) - 0.5 (1 - Φ(0.5)) = 0.3520653 - 0.5 * 0.3085375 = 0.1977966
# Capped at U_max = 2.5, policy1 loses ∫ from 2.5 to inf of P(U ≥ u) du
#   = φ(3) - 3 (1 - Φ(3)) = 0.0044318 - 3 * 0.0013499 = 0.0003821 -> 0.1974145
# (policy0's tail past 2.5 is 25 σ away: 0). EI prefers the uncertain policy1.
MEAN_1T = [[0.0, -0.5]]
STD_1T = [[0.1, 1.0]]


def test_expected_improvement_by_hand():
    belief = np.array([1.0])
    assert expected_improvement(belief, MEAN_1T, STD_1T, 0.0, math.inf) == pytest.approx(
        [0.0398942, 0.1977966], abs=1e-6)
    assert expected_improvement(belief, MEAN_1T, STD_1T, 0.0, 2.5) == pytest.approx(
        [0.0398942, 0.1974145], abs=1e-6)


# PI with U⁺ = Ū + (U_max - Ū) / 2 = 1.25:
#   policy0: P(N(0, 0.1) ≥ 1.25) = P(Z ≥ 12.5) ≈ 4e-36
#   policy1: P(N(-0.5, 1) ≥ 1.25) = P(Z ≥ 1.75) = 0.0400592
def test_probability_of_improvement_by_hand():
    scores = probability_of_improvement(np.array([1.0]), MEAN_1T, STD_1T, 1.25)
    assert scores == pytest.approx([0.0, 0.0400592], abs=1e-7)


@pytest.mark.parametrize("spec", ["bpr", "bpr-pi"])
def test_bpr_rules_choose_by_hand(spec):
    model = model_of(MEAN_1T, STD_1T)
    assert make_selector(spec, model.policies, model, seed=0, forgetting=0.0).choose() == \
        "policy1"


# Where the two rules part: one type, policy0 ~ N(0, 0.2), policy1 ~ N(-0.8, 0.6). Ū = 0,
# U_max = max(0 + 0.6, -0.8 + 1.8) = 1.0, U⁺ = 0.5.
#   EI: policy0 0.2 φ(0) = 0.0797885 (its tail past 1.0, 5 σ away, ~1e-8);
#       policy1 0.6 φ(4/3) - 0.8 (1 - Φ(4/3)) = 0.0984060 - 0.0729688 = 0.0254372, less its tail
#       past 1.0 (z = 3): 0.6 φ(3) - 1.8 (1 - Φ(3)) = 0.0026591 - 0.0024298 = 0.0002293
#       -> 0.0252079: EI keeps the good sure policy0.
#   PI: policy0 P(Z ≥ 2.5) = 0.0062097; policy1 P(Z ≥ 1.3 / 0.6 = 2.1667) = 0.0151300:
#       PI, which asks only for reaching U⁺, takes the long shot policy1.
MEAN_PART, STD_PART = [[0.0, -0.8]], [[0.2, 0.6]]


def test_ei_and_pi_part_by_hand():
    belief = np.array([1.0])
    assert expected_improvement(belief, MEAN_PART, STD_PART, 0.0, 1.0) == pytest.approx(
        [0.0797885, 0.0252079], abs=1e-6)
    assert probability_of_improvement(belief, MEAN_PART, STD_PART, 0.5) == pytest.approx(
        [0.0062097, 0.0151300], abs=1e-6)
    model = model_of(MEAN_PART, STD_PART)
    assert make_selector("bpr", model.policies, model, 0, 0.0).choose() == "policy0"
    assert make_selector("bpr-pi", model.policies, model, 0, 0.0).choose() == "policy1"


# Two types that want opposite policies, belief (0.9, 0.1): μ = [[1, 0], [0, 1]], σ = 0.1.
# Ū = 0.9. EI of policy0 = 0.9 * (σ φ(-1) + 0.1 (1 - Φ(-1))) = 0.9 * (0.0241971 + 0.0841345)
# = 0.0974985 (policy1's only on type1: 0.1 * 0.1083316 = 0.0108332; each less the ~4e-5
# tail past U_max = 1.3). PI at U⁺ = 1.1: P(Z ≥ 1) = 0.1586553, so policy0 0.9 x that =
# 0.1427898, policy1 0.1 x that = 0.0158655.
def test_the_belief_decides_the_policy():
    belief = np.array([0.9, 0.1])
    mean, std = np.array([[1.0, 0.0], [0.0, 1.0]]), np.full((2, 2), 0.1)
    assert expected_improvement(belief, mean, std, 0.9, math.inf) == pytest.approx(
        [0.0974985, 0.0108332], abs=1e-6)
    assert probability_of_improvement(belief, mean, std, 1.1) == pytest.approx(
        [0.1427898, 0.0158655], abs=1e-6)


# The utility cannot pass 1 (a success at once, nothing else): U_max is capped there. The
# fabric figures that showed why, one type: a sure policy N(0.77, 0.2) (policy9 on a
# non-collaborating beginner) and an erratic one N(0.36, 0.6) (the reactive robot: it fails
# some of his tasks). Ū = 0.77. Uncapped, EI pays for the erratic policy's chances above 1,
# which no task can score: 0.0882 against 0.0798; capped at 1 the sure policy leads, 0.0674
# against 0.0442 (numbers from the closed form above).
def test_u_max_is_the_utilitys_top_so_ei_does_not_buy_impossible_upside():
    from ros_hrc.agents.selectors import utility_ceiling
    mean, std = [[0.77, 0.36]], [[0.2, 0.6]]
    assert utility_ceiling(np.array(mean), np.array(std)) == 1.0
    assert utility_ceiling(np.array([[0.1]]), np.array([[0.1]])) == pytest.approx(0.4)
    belief = np.array([1.0])
    assert expected_improvement(belief, mean, std, 0.77, math.inf) == pytest.approx(
        [0.0797885, 0.0881734], abs=1e-6)
    assert expected_improvement(belief, mean, std, 0.77, 1.0) == pytest.approx(
        [0.0673678, 0.0442149], abs=1e-6)
    model = model_of(mean, std)
    assert make_selector("bpr", model.policies, model, 0, 0.0).choose() == "policy0"


# -- FABRIC's variant -----------------------------------------------------------------------
# Their update, from the uniform belief, codes (1, 33):
#   A: (0.5 + 1e-5) (0.5 + 1e-4)(0.5 + 1e-4), B: (0.5 + 1e-5) (0.2 + 1e-4)(0.8 + 1e-4)
#   -> β(A) = 0.25010001 / (0.25010001 + 0.16010001) = 0.6097025
def test_fabric_update_by_hand():
    assert fabric_type_posterior(np.array([0.5, 0.5]), ROWS_AB, (1, 33)) == pytest.approx(
        [0.6097025, 0.3902975], abs=1e-7)


# A type the belief has ruled out comes back only through the 1e-5: belief (1, 0), ten steps
# of code 33: B / A = 1e-5 (0.8001 / 0.5001)^10 / (1 + 1e-5) = 1e-5 * 109.8703 -> β(B) =
# 0.0010976. The paper's update keeps β(B) = 0 for ever.
def test_fabric_update_revives_a_ruled_out_type_by_its_epsilon_only():
    posterior = fabric_type_posterior(np.array([1.0, 0.0]), ROWS_AB, (33,) * 10)
    assert posterior[1] == pytest.approx(0.0010976, rel=1e-3)
    paper = type_posterior(np.array([1.0, 0.0]), signature_log_likelihood(ROWS_AB, (33,) * 10))
    assert paper[1] == 0.0


# Their score collapses to one point when Ū = max μ + max σ: two types, μ = [[1, 0], [1, 0]],
# σ = 0: Ū = 1 (policy0), the grid is 100 times U = 1, and with their σ + 2:
#   policy0: 100 * N(1; 1, 2) = 100 / (2 sqrt(2π)) = 19.9471
#   policy1: 100 * N(1; 0, 2) = 19.9471 * exp(-1/8) = 17.6033
def test_fabric_score_on_a_collapsed_grid():
    scores = fabric_scores(np.array([0.5, 0.5]), np.array([[1.0, 0.0], [1.0, 0.0]]),
                           np.zeros((2, 2)))
    assert scores == pytest.approx([19.9471, 17.6033], abs=1e-4)


# One type, one policy N(0, 1): Ū = 0, top = 0 + 1, grid k/100 (k = 0..99), σ + 2 = 3.
# The left Riemann sum of the N(0, 3) density over [0, 1) with step 1/100, divided by the step:
# 100 (Φ(1/3) - 1/2) + (φ3(0) - φ3(1)) / 2 = 13.05587 + (0.1329808 - 0.1257944) / 2 = 13.0595
# (φ3 the N(0, 3) density): a sum of densities, the probability above Ū times 100.
def test_fabric_score_is_a_density_sum_over_their_grid():
    assert fabric_scores(np.array([1.0]), np.array([[0.0]]), np.array([[1.0]])) == \
        pytest.approx([13.0595], abs=2e-4)


def test_fabric_selector_takes_their_score_and_updates_their_way():
    model = model_of([[1.0, 0.0], [1.0, 0.0]], [[0.05, 0.05], [0.05, 0.05]], rows=ROWS_AB)
    selector = make_selector("bpr-fabric", model.policies, model, seed=3, forgetting=0.5)
    assert selector.choose() == "policy0"
    selector.observe(TaskResult("policy0", (1, 33), 0.9))
    assert selector.belief() == pytest.approx([0.6097025, 0.3902975], abs=1e-7)   # no floor


# -- convergence, and forgetting -------------------------------------------------------------
# Three types over three codes: type0 (1: 0.6, 33: 0.3, 17: 0.1), type1 (0.3, 0.6, 0.1),
# type2 (0.2, 0.2, 0.6). A task: 10 steps drawn from the true type's row.
ROWS_3 = signature_rows({1: 0.6, 33: 0.3, 17: 0.1}, {1: 0.3, 33: 0.6, 17: 0.1},
                        {1: 0.2, 33: 0.2, 17: 0.6})
MODEL_3 = model_of(np.zeros((3, 2)), np.ones((3, 2)), rows=ROWS_3)


def draw_task(rng, true_type):
    row = ROWS_3[true_type]
    return tuple(int(c) for c in rng.choice(SIGNATURE_CODES, size=10, p=row))


def tasks_to_switch(spec, forgetting, seed=3):
    """Ten tasks of type0, then type1's: the belief's argmax after the first ten, and how many
    of type1's tasks it takes for the argmax to be type1 (None: not within 30)."""
    rng = np.random.default_rng(seed)
    selector = make_selector(spec, MODEL_3.policies, MODEL_3, seed=seed, forgetting=forgetting)
    for _ in range(10):
        selector.observe(TaskResult(selector.choose(), draw_task(rng, 0), 0.0))
    first = int(np.argmax(selector.belief()))
    for n in range(1, 31):
        selector.observe(TaskResult(selector.choose(), draw_task(rng, 1), 0.0))
        if int(np.argmax(selector.belief())) == 1:
            return first, n
    return first, None


@pytest.mark.parametrize("spec", ["bpr", "bpr-pi", "bpr-fabric"])
def test_a_known_type_is_identified(spec):
    rng = np.random.default_rng(5)
    selector = make_selector(spec, MODEL_3.policies, MODEL_3, seed=5,
                             forgetting=DEFAULT_FORGETTING)
    for _ in range(6):
        selector.observe(TaskResult(selector.choose(), draw_task(rng, 2), 0.0))
    assert int(np.argmax(selector.belief())) == 2
    assert selector.belief()[2] > 0.9


def test_forgetting_reidentifies_a_switched_human_sooner():
    first, with_floor = tasks_to_switch("bpr", DEFAULT_FORGETTING)
    assert first == 0
    assert with_floor is not None and with_floor <= 3
    first, without = tasks_to_switch("bpr", 0.0)
    assert first == 0
    assert without is None or without >= with_floor + 3
    # FABRIC's belief forgets nothing beyond its 1e-5: slower too.
    _, fabric = tasks_to_switch("bpr-fabric", 0.0)
    assert fabric is None or fabric >= with_floor + 3
    # Not one lucky sequence: over twelve, the floor's switch takes a third of the time or less.
    def mean_switch(forgetting):
        return np.mean([tasks_to_switch("bpr", forgetting, seed)[1] or 31 for seed in range(12)])

    assert mean_switch(DEFAULT_FORGETTING) * 3 <= mean_switch(0.0)


# -- the bandit --------------------------------------------------------------------------------
# Fixed utilities per policy: a 1.0 (reward 1), b -1.5 (reward 0), c -0.25 (reward 0.5).
# UCB1 plays each once, then the largest mean + sqrt(2 ln n / n_π). A worse policy π comes
# back while its bound still reaches a's: sqrt(2 ln n / n_π) - sqrt(2 ln n / n_a) >= the gap
# of the means, so the further behind, the rarer (b, gap 1, fewer than c, gap 0.5); in 60
# tasks a is played most, and most of the last 20 (this seed: a 45, b 5, c 10 times).
TABLE = {"a": 1.0, "b": -1.5, "c": -0.25}


def play_bandit(seed, n=60):
    selector = make_selector("bandit", tuple(TABLE), None, seed=seed, forgetting=0.0)
    choices = []
    for _ in range(n):
        policy = selector.choose()
        choices.append(policy)
        selector.observe(TaskResult(policy, (), TABLE[policy]))
    return choices


def test_bandit_settles_on_the_best_policy():
    choices = play_bandit(seed=7)
    assert sorted(choices[:3]) == ["a", "b", "c"]                 # each once first
    assert max(TABLE, key=choices.count) == "a"
    assert choices[-20:].count("a") >= 16
    assert choices.count("b") < choices.count("c") < choices.count("a")


def test_bandit_is_reproducible_under_its_seed():
    assert play_bandit(seed=7) == play_bandit(seed=7)
    firsts = {tuple(play_bandit(seed=s, n=3)) for s in range(12)}
    assert len(firsts) > 1                                       # the seed orders the first plays
    selector = make_selector("bandit", tuple(TABLE), None, seed=1, forgetting=0.0)
    assert selector.type_names == () and selector.belief().size == 0
    with pytest.raises(ValueError, match="not in the library"):
        selector.observe(TaskResult("z", (), 0.0))


def test_bandit_reward_maps_the_utility_onto_unit_interval():
    assert [bandit_reward(u) for u in (1.0, -1.5, -0.25, 3.0, -9.0)] == pytest.approx(
        [1.0, 0.0, 0.5, 1.0, 0.0])


# -- fixed, random, oracle -------------------------------------------------------------------
def test_fixed_always_plays_its_policy():
    selector = make_selector("fixed:b", ("a", "b"), None, seed=0, forgetting=0.0)
    assert selector.name == "fixed:b"
    for _ in range(5):
        assert selector.choose() == "b"
        selector.observe(TaskResult("b", (1,), -1.0))
    assert selector.belief().size == 0


def test_random_is_uniform_and_reproducible():
    def draws(seed):
        selector = make_selector("random", ("a", "b", "c"), None, seed=seed, forgetting=0.0)
        return [selector.choose() for _ in range(3000)]

    first = draws(4)
    assert first == draws(4) and first != draws(5)
    for policy in "abc":
        assert first.count(policy) / 3000 == pytest.approx(1 / 3, abs=0.03)


def test_oracle_plays_the_best_policy_of_the_true_type():
    # type0 best with policy1 (0.8), type1 best with policy0 (0.6); on average over the types
    # policy1: (0.8 + 0.5) / 2 = 0.65 > policy0: (0.1 + 0.6) / 2 = 0.35.
    model = model_of([[0.1, 0.8], [0.6, 0.5]], np.full((2, 2), 0.1), types=("calm", "tired"))
    oracle = make_selector("oracle", model.policies, model, seed=0, forgetting=0.0)
    oracle.tell_true_type("tired")
    assert oracle.choose() == "policy0" and oracle.note == ""
    assert oracle.belief() == pytest.approx([0.0, 1.0])
    oracle.tell_true_type("calm")
    assert oracle.choose() == "policy1"
    oracle.tell_true_type("stranger")
    assert oracle.choose() == "policy1"
    assert "'stranger' is not one the model was trained on" in oracle.note
    assert oracle.belief() == pytest.approx([0.5, 0.5])


# -- make_selector's refusals ------------------------------------------------------------------
def test_make_selector_refuses_in_one_line():
    model = model_of(MEAN_1T, STD_1T)
    cases = [
        ("banditt", model, 0, 0.0, "unknown selector 'banditt'; did you mean bandit?"),
        ("beast", model, 0, 0.0, r"\(known: random, bpr, bpr-pi, bpr-fabric, bandit, oracle, "
                                 r"or module:Class\); also fixed:<policy>"),
        ("ros_hrc.agents.selectors:TaskResult", model, 0, 0.0,
         "selector ros_hrc.agents.selectors:TaskResult: TaskResult is not a subclass of "
         "ros_hrc.agents.selectors.Selector"),
        ("fixed", model, 0, 0.0, "names no policy"),
        ("fixed:policy9", model, 0, 0.0, "no policy 'policy9' in the library"),
        ("random:x", model, 0, 0.0, "takes no argument"),
        ("bpr", None, 0, 0.0, "needs a selector model.*make train-selector"),
        ("oracle", None, 0, 0.0, "needs a selector model"),
        ("bpr", model, 0, 1.0, "bpr_forgetting must be a number from 0 to below 1"),
        ("bpr", model, 0, -0.1, "bpr_forgetting"),
        ("random", model, -1, 0.0, "seed must be an integer"),
    ]
    for spec, given, seed, forgetting, message in cases:
        with pytest.raises(ValueError, match=message) as caught:
            make_selector(spec, model.policies, given, seed=seed, forgetting=forgetting)
        assert "\n" not in str(caught.value)
    with pytest.raises(ValueError, match="the selector model is of the policies"):
        make_selector("bpr", ("policy1", "policy0"), model, seed=0, forgetting=0.0)
    with pytest.raises(ValueError, match="not in the selector model"):
        make_selector("bpr", model.policies, model, 0, 0.0).observe(TaskResult("x", (), 0.0))


def test_every_selector_name_is_made():
    from ros_hrc import registry
    model = model_of(MEAN_1T, STD_1T)
    for name in ("fixed",) + registry.names(registry.SELECTORS):
        spec = "fixed:policy0" if name == "fixed" else name
        selector = make_selector(spec, model.policies, model, seed=2, forgetting=0.05)
        assert selector.name == spec
        assert selector.choose() in model.policies
        assert len(selector.belief()) == len(selector.type_names)
