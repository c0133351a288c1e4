"""Models built in code from arrays, so the solver tests do not depend on the parsers.

A module of its own (not conftest) so that tests can import it by a name no other test folder
uses.
"""
from typing import Sequence

import numpy as np
import scipy.sparse as sp

from ros_hrc.pomdp.model import Model

#: The optimal value of Tiger (discount 0.95) at the uniform belief, as published for SARSOP.
TIGER_OPTIMUM = 19.37


def make_model(T: np.ndarray, O: np.ndarray, R: np.ndarray, discount: float,
               initial: Sequence[float], states=None, actions=None, observations=None,
               fully_observable: bool = False, name: str = "test") -> Model:
    """A Model from dense arrays T (A,S,S'), O (A,S',Z), R (A,S,S')."""
    A, S, _ = T.shape
    Z = O.shape[2]
    model = Model(
        states=list(states or [f"s{i}" for i in range(S)]),
        actions=list(actions or [f"a{i}" for i in range(A)]),
        observations=list(observations or [f"o{i}" for i in range(Z)]),
        discount=discount,
        initial_belief=np.asarray(initial, dtype=float),
        T=[sp.csr_matrix(T[a]) for a in range(A)],
        O=[sp.csr_matrix(O[a]) for a in range(A)],
        R=[sp.csr_matrix(R[a]) for a in range(A)],
        fully_observable=fully_observable,
        name=name,
    )
    model.validate()
    return model


def build_tiger(discount: float = 0.95) -> Model:
    """The classic Tiger problem (Kaelbling, Littman, Cassandra 1998)."""
    T = np.empty((3, 2, 2))
    T[0] = np.eye(2)                       # listen: the tiger stays
    T[1] = T[2] = 0.5                      # opening a door resets the problem
    O = np.empty((3, 2, 2))
    O[0] = [[0.85, 0.15], [0.15, 0.85]]    # listening is right 85 % of the time
    O[1] = O[2] = 0.5
    R = np.empty((3, 2, 2))
    R[0] = -1.0
    R[1] = [[-100.0, -100.0], [10.0, 10.0]]   # open-left: tiger-left eats you
    R[2] = [[10.0, 10.0], [-100.0, -100.0]]
    return make_model(T, O, R, discount, [0.5, 0.5],
                      states=["tiger-left", "tiger-right"],
                      actions=["listen", "open-left", "open-right"],
                      observations=["tiger-left", "tiger-right"], name="tiger")


def build_chain(n: int = 4, discount: float = 0.9, goal_reward: float = 1.0) -> Model:
    """A deterministic chain MDP: 'right' moves one step right, 'stay' stays; reward on reaching
    (or staying in) the last state. V*(s) = γ^(n-2-s) / (1-γ) for s < n-1, 1/(1-γ) at the end."""
    T = np.zeros((2, n, n))
    for s in range(n):
        T[0, s, s] = 1.0
        T[1, s, min(s + 1, n - 1)] = 1.0
    O = np.stack([np.eye(n), np.eye(n)])
    R = np.zeros((2, n, n))
    R[:, :, n - 1] = goal_reward
    initial = np.zeros(n)
    initial[0] = 1.0
    return make_model(T, O, R, discount, initial, actions=["stay", "right"],
                      observations=[f"s{i}" for i in range(n)], fully_observable=True,
                      name="chain")
