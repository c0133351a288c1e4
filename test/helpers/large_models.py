"""Large sparse models for the memory and time tests, written in a few kilobytes.

``torus_pomdpx(nx, ny)``: a rover on an nx x ny torus, two state variables (``x``, ``y``), so
the flat model has nx·ny states while the file stays small and reads in a moment. Actions:
``stay``; ``east`` and ``north`` move one cell with probability 0.9 (else stay). One observation
variable, ``beacon``: ``near`` with probability 0.8 in column x0, ``far`` everywhere else. Reward
1 for acting in column x0. T has at most 2 non-zeros per row, so 50,000 states are 250,000
non-zeros: a solver that makes an S x S array (20 GB) is caught at once. ``torus``: the
fixture of the memory tests, that model at 50,000 states in a file.
"""
import pytest


def _moves(var: str, action: str, n: int) -> str:
    entries = []
    for i in range(n):
        entries.append(f"<Entry><Instance>{action} {var}{i} {var}{(i + 1) % n}</Instance>"
                       f"<ProbTable>0.9</ProbTable></Entry>")
        entries.append(f"<Entry><Instance>{action} {var}{i} {var}{i}</Instance>"
                       f"<ProbTable>0.1</ProbTable></Entry>")
    return "\n".join(entries)


def _transition(var: str, mover: str, n: int) -> str:
    return (f"<CondProb><Var>{var}_1</Var><Parent>act {var}_0</Parent><Parameter type=\"TBL\">\n"
            f"<Entry><Instance>* - -</Instance><ProbTable>identity</ProbTable></Entry>\n"
            f"<Entry><Instance>{mover} * *</Instance><ProbTable>0</ProbTable></Entry>\n"
            f"{_moves(var, mover, n)}\n</Parameter></CondProb>")


def torus_pomdpx(nx: int, ny: int, discount: float = 0.95) -> str:
    xs = " ".join(f"x{i}" for i in range(nx))
    ys = " ".join(f"y{i}" for i in range(ny))
    beacon = " ".join(["0.2 0.8"] + ["1 0"] * (nx - 1))
    return f"""<?xml version="1.0" encoding="UTF-8"?>
<pomdpx version="1.0" id="torus">
<Discount>{discount}</Discount>
<Variable>
  <StateVar vnamePrev="x_0" vnameCurr="x_1"><ValueEnum>{xs}</ValueEnum></StateVar>
  <StateVar vnamePrev="y_0" vnameCurr="y_1"><ValueEnum>{ys}</ValueEnum></StateVar>
  <ObsVar vname="beacon"><ValueEnum>far near</ValueEnum></ObsVar>
  <ActionVar vname="act"><ValueEnum>stay east north</ValueEnum></ActionVar>
  <RewardVar vname="reward"/>
</Variable>
<InitialStateBelief>
  <CondProb><Var>x_0</Var><Parent>null</Parent><Parameter type="TBL">
    <Entry><Instance>-</Instance><ProbTable>uniform</ProbTable></Entry></Parameter></CondProb>
  <CondProb><Var>y_0</Var><Parent>null</Parent><Parameter type="TBL">
    <Entry><Instance>-</Instance><ProbTable>uniform</ProbTable></Entry></Parameter></CondProb>
</InitialStateBelief>
<StateTransitionFunction>
{_transition("x", "east", nx)}
{_transition("y", "north", ny)}
</StateTransitionFunction>
<ObsFunction>
  <CondProb><Var>beacon</Var><Parent>x_1</Parent><Parameter type="TBL">
    <Entry><Instance>- -</Instance><ProbTable>{beacon}</ProbTable></Entry>
  </Parameter></CondProb>
</ObsFunction>
<RewardFunction>
  <Func><Var>reward</Var><Parent>x_0</Parent><Parameter type="TBL">
    <Entry><Instance>x0</Instance><ValueTable>1</ValueTable></Entry>
  </Parameter></Func>
</RewardFunction>
</pomdpx>
"""


#: 250 x 200 cells: 50,000 states, 250,000 non-zeros in T.
NX, NY = 250, 200


@pytest.fixture(scope="module")
def torus(tmp_path_factory):
    """The 50,000-state torus as a POMDPX file, written once per test module."""
    path = tmp_path_factory.mktemp("large") / "torus.pomdpx"
    path.write_text(torus_pomdpx(NX, NY))
    return path
