"""The offline solver's values on every shipped model and the test models, pinned (issue #24).

Each row is a bracket [lower, upper] of the optimal value at the start, computed with the solver
as it was before issue #24's changes (commit 020e7db's bounds logic, to 2e-4). Both brackets
are valid bounds on the same number, so today's solver, run with the exact stopping rule at
precision 1e-3, must return a gap <= 1e-3 whose interval meets the pinned one. A model file
that changed (its sha256 differs) fails with a message saying so: recompute its row with
``hrc_pomdp solve FILE --precision 2e-4``.
"""
import hashlib
from pathlib import Path

import pytest

from ros_hrc.pomdp import offline
from ros_hrc.pomdp.io import load_model

from solver_models import build_chain, build_tiger

ROOT = Path(__file__).resolve().parents[3]
PRECISION = 1e-3

#: (file, first 12 hex digits of its sha256, lower, upper)
PINNED = [
    ("bench/models/robot_fitted_9a32e6f.pomdp", "c77ba63fe819", 80.82884672422006, 80.82904428376258),
    ("models/fabric/human/beginner_nontired_collaborative.pomdpx", "251b05735baf", 134.4716150119241, 134.4716169759783),
    ("models/fabric/human/beginner_nontired_noncollaborative.pomdpx", "219b3f5a9484", 129.45322812423396, 129.45323008828817),
    ("models/fabric/human/beginner_tired_collaborative.pomdpx", "8191daa7ad7e", 149.6674881455262, 149.66749014279543),
    ("models/fabric/human/beginner_tired_noncollaborative.pomdpx", "ba71331d3c5d", 137.78732682659583, 137.78732882386507),
    ("models/fabric/human/distracted_collaborative.pomdpx", "8e2fce4c494d", 109.52439395321183, 109.5243959476651),
    ("models/fabric/human/distracted_noncollaborative.pomdpx", "7a97791baf84", 78.03176435273672, 78.0317663443782),
    ("models/fabric/human/expert_nontired_collaborative.pomdpx", "548a85edbc11", 222.12470355274016, 222.1247055185909),
    ("models/fabric/human/expert_nontired_noncollaborative.pomdpx", "1b3100b01449", 203.58043328318215, 203.5804352490329),
    ("models/fabric/human/expert_tired_collaborative.pomdpx", "e2a7dda376a7", 193.39012753338432, 193.39012949923506),
    ("models/fabric/human/expert_tired_noncollaborative.pomdpx", "a0b092c4edb1", 190.65219469116758, 190.65219665701832),
    ("models/fabric/robot/reactive.pomdpx", "1e91e86f2a54", 236.8748891751794, 236.8748911646692),
    ("models/human/beginner.pomdpx", "41b81931f219", 449.00221532529457, 449.00221729489994),
    ("models/human/confident_novice.pomdpx", "c75f99909eca", 41.610167512303626, 41.61016949152533),
    ("models/human/deliberator.pomdpx", "1af087348084", 46.482922959192585, 46.48292493841499),
    ("models/human/distracted.pomdpx", "1f812e37562c", 241.64182829391513, 241.64183025976587),
    ("models/human/drops_and_waits.pomdpx", "84754551ba7c", 39.307998216721174, 39.30800019594288),
    ("models/human/early_warner.pomdpx", "1ee92f135224", 45.595664883686126, 45.59566686290853),
    ("models/human/evaluating.pomdpx", "67db46575daf", 476.90645972426785, 476.9064617024576),
    ("models/human/expert.pomdpx", "74aaa720fbf4", 249.4456743090923, 249.44567627494584),
    ("models/human/humanModel.pomdpx", "fb04e314bdcd", 245.34294937036105, 245.3429513362118),
    ("models/human/humanModel_completed.pomdpx", "979ac8b5927c", 245.57039277098983, 245.57039473684335),
    ("models/human/looks_away_first.pomdpx", "9905985f5c10", 45.72474713068498, 45.724749109907386),
    ("models/human/persistent_failer.pomdpx", "1b7d7210633e", 33.01593273887878, 33.015934718101185),
    ("models/human/slow_steady.pomdpx", "ce1ceef6f351", 46.228932226241504, 46.22893420546391),
    ("models/human/tired.pomdpx", "0b2b00d476a0", 831.1529913593014, 831.1529933481144),
    ("models/human/tires_late.pomdpx", "c30cbd17a683", 43.982546539010656, 43.98254851823306),
    ("models/human/walker.pomdpx", "5486233bcc43", 45.78731513459223, 45.78731711381463),
    ("models/robot/robot.pomdp", "cea924799b0c", 6.898378160189495, 6.898570248324281),
    ("models/robot/robot.pomdpx", "ff51302f3979", 6.898378160189495, 6.898570248324281),
    ("models/robot/robot_completed.pomdp", "9d8da4efc473", 1.2468313457259848, 1.2470246118384072),
    ("models/robot/robot_considerate.pomdp", "c45b501350e2", 16.3871581435329, 16.38735517050351),
    ("models/robot/robot_considerate_fitted.pomdp", "cfb14c841fb3", 11.464055580438254, 11.464254990735315),
    ("models/robot/robot_fitted.pomdp", "8193b676d504", 46.750319350064274, 46.75051905208523),
    # issue #40's learning prior, pinned with today's solver (hrc_pomdp solve --precision 2e-4)
    ("models/robot/robot_utility_fitted.pomdp", "27e9b5789001", 16.22352535689197, 16.22372109387559),
    ("test/fixtures/tiger.95.pomdp", "922b98f9e98a", 19.37133818637241, 19.371433798542782),
]


#: FABRIC's robot POMDPs (discount 0.98): neither today's solver nor the one before issue #24
#: closes their gap to 1e-3 in minutes (base.pomdpx: [126.6, 136.3] after 150 s), so there is
#: no bracket to pin; DESPOT plans on them online.
UNPINNED = {f"models/fabric/robot/{name}.pomdpx"
            for name in ("base", *(f"policy{n}" for n in (1, 3, 4, 5, 6, 7, 8, 9, 10, 11, 12)))}
#: The robot models of human types (issue #31, hrc_fit --types): the solver does not close
#: their gap to 1e-3 in minutes either (the seed's: 0.065 after 300 s; docs/performance.md).
UNPINNED |= {"models/robot/robot_types.pomdp", "models/fabric/robot/robot_types.pomdp"}
#: Fabric's learning prior (issue #40): fabric's base refitted, discount 0.98, as base.
UNPINNED |= {"models/fabric/robot/robot_utility_fitted.pomdp"}


def test_every_shipped_model_is_pinned():
    shipped = {str(p.relative_to(ROOT))
               for folder in ("models/robot", "models/human", "models/fabric/robot",
                              "models/fabric/human")
               for p in (ROOT / folder).iterdir() if p.suffix in (".pomdp", ".pomdpx")}
    assert shipped - UNPINNED <= {row[0] for row in PINNED}


@pytest.mark.parametrize("path, digest, lower, upper", PINNED, ids=[r[0] for r in PINNED])
def test_the_value_at_the_start_is_the_pinned_one(path, digest, lower, upper):
    data = (ROOT / path).read_bytes()
    assert hashlib.sha256(data).hexdigest()[:12] == digest, (
        f"{path} changed since its value was pinned: recompute its row")
    policy = offline.solve(load_model(ROOT / path), timeout=600.0, precision=PRECISION)
    # The exact stopping rule: the gap at the start is within the precision asked for.
    assert policy.upper - policy.lower <= PRECISION
    # Both intervals hold the optimal value, so they meet.
    assert policy.lower <= upper + 1e-9 and policy.upper >= lower - 1e-9, \
        (policy.lower, policy.upper)


def test_the_code_built_test_models_keep_their_values():
    tiger = offline.solve(build_tiger(), timeout=600.0, precision=PRECISION)
    assert tiger.upper - tiger.lower <= PRECISION
    assert tiger.lower <= 19.371433798542782 + 1e-9 and tiger.upper >= 19.37133818637241 - 1e-9
    chain = build_chain(4, 0.9)
    policy = offline.solve(chain, timeout=600.0, precision=PRECISION)
    exact = 0.9 ** 2 / (1 - 0.9)                # V*(s0) = γ^(n-2) / (1-γ)
    assert policy.lower - 1e-9 <= exact <= policy.upper + 1e-9
