"""An offline policy as a set of alpha vectors, and its file format.

A policy is a set of vectors α_i over states, each tagged with an action. At belief b the policy
takes the action of the vector maximising α_i · b, and that maximum is the policy's value (a lower
bound on the optimum when the vectors come from a point-based solver). An MDP solved by value
iteration is stored the same way, one vector Q[a] per action: for the point-mass beliefs of a
fully observable model, argmax_a Q[a] · b is exactly the greedy MDP action.

File format (``save``/``load``): a numpy ``.npz`` archive (zip of ``.npy`` arrays, no pickles),
written to exactly the path given, with these arrays:

    format         "ros_hrc-policy"
    version        1
    kind           "alpha" (point-based POMDP solver) or "mdp" (value iteration)
    alphas         float64 (k, S): the vectors
    actions        int64   (k,):   the action index of each vector
    state_names    str     (S,)
    action_names   str     (A,)
    discount       float64 ()
    lower, upper   float64 ():     bounds on the optimal value from the model's initial belief
                                   (with mixed observability Σ_k P(k) V*(b_k): Model.start_split)
    model_name     str     ()
    stats_json     str     ():     solver statistics (seconds, trials, ...) as a JSON object

Read one with ``numpy.load(path)``; the file name's extension does not matter. ``save`` writes
the whole file or nothing; ``load`` refuses non-finite vectors and, given a memory limit, an
archive whose arrays would not fit in it (from the sizes its zip directory declares, before
anything is unpacked).
"""
from __future__ import annotations

import json
import os
import zipfile
from dataclasses import dataclass, field
from typing import Dict, List, Optional

import numpy as np

from ros_hrc.errors import SolverError
from ros_hrc.pomdp import memory
from ros_hrc.pomdp.model import Model
from ros_hrc.pomdp.output import write_atomically

FORMAT = "ros_hrc-policy"
VERSION = 1


@dataclass
class Policy:
    """Alpha vectors with their actions, plus the bounds the solver proved at the initial belief."""

    alphas: np.ndarray                  # (k, S)
    actions: np.ndarray                 # (k,)
    state_names: List[str]
    action_names: List[str]
    discount: float
    lower: float = float("nan")
    upper: float = float("nan")
    kind: str = "alpha"
    model_name: str = ""
    stats: dict = field(default_factory=dict)

    def __post_init__(self) -> None:
        self.alphas = np.atleast_2d(np.asarray(self.alphas, dtype=float))
        self.actions = np.asarray(self.actions, dtype=np.int64).ravel()
        if self.alphas.shape[0] != self.actions.size or self.actions.size == 0:
            raise SolverError(f"policy has {self.alphas.shape[0]} vectors and "
                              f"{self.actions.size} actions; need the same, at least one")
        if self.alphas.shape[1] != len(self.state_names):
            raise SolverError(f"policy vectors have {self.alphas.shape[1]} entries for "
                              f"{len(self.state_names)} states")

    @property
    def n_states(self) -> int:
        return self.alphas.shape[1]

    def best(self, belief: np.ndarray) -> int:
        """Index of the vector that is best at ``belief``."""
        return int(np.argmax(self.alphas @ np.asarray(belief, dtype=float)))

    def action(self, belief: np.ndarray) -> int:
        """The action the policy takes at ``belief`` (a distribution over states)."""
        return int(self.actions[self.best(belief)])

    def value(self, belief: np.ndarray) -> float:
        """The policy's value at ``belief``: max_i α_i · b."""
        return float(np.max(self.alphas @ np.asarray(belief, dtype=float)))

    def action_values(self, belief: np.ndarray) -> Dict[int, float]:
        """Each action's value at ``belief`` under the policy: the best α_i · b over the
        vectors of that action (the policy takes the action of the largest); an action without
        a vector has none and is left out."""
        values = self.alphas @ np.asarray(belief, dtype=float)
        best = np.full(int(self.actions.max()) + 1, -np.inf)
        np.maximum.at(best, self.actions, values)
        return {a: float(v) for a, v in enumerate(best.tolist()) if v != -np.inf}

    def check(self, model: Model) -> None:
        """Raise SolverError unless the policy was made for a model of this shape."""
        if self.n_states != model.n_states:
            raise SolverError(f"policy is for {self.n_states} states, model has {model.n_states}")
        if self.actions.max() >= model.n_actions or self.actions.min() < 0:
            raise SolverError(f"policy uses action {int(self.actions.max())}, "
                              f"model has {model.n_actions} actions (0..{model.n_actions - 1})")

    def save(self, path: str) -> None:
        """Write the policy to ``path`` (npz format above, exactly that file name), whole or
        not at all."""
        def write(fh) -> None:
            np.savez_compressed(
                fh, format=np.array(FORMAT), version=np.array(VERSION), kind=np.array(self.kind),
                alphas=self.alphas, actions=self.actions,
                state_names=np.array(self.state_names, dtype=str),
                action_names=np.array(self.action_names, dtype=str),
                discount=np.array(float(self.discount)), lower=np.array(float(self.lower)),
                upper=np.array(float(self.upper)), model_name=np.array(self.model_name),
                stats_json=np.array(json.dumps(self.stats, default=float)))

        write_atomically(path, write)

    @classmethod
    def load(cls, path: str, memory_limit: Optional[int] = None,
             memory_in_use: int = 0) -> "Policy":
        """Read a policy written by ``save``; SolverError naming the file when it is not one,
        MemoryLimitError when its arrays and ``memory_in_use`` bytes would need more than
        ``memory_limit`` bytes."""
        try:
            if not os.path.isfile(path):
                raise SolverError(f"{path}: no such policy file")
            if not zipfile.is_zipfile(path):
                raise SolverError(f"{path}: not a policy file (expected the .npz archive that "
                                  f"'hrc_pomdp solve -o' writes)")
            with zipfile.ZipFile(path) as archive:
                unpacked = sum(info.file_size for info in archive.infolist())
            # Each array is unpacked, then checked and copied once.
            memory.require(memory_in_use + 2 * unpacked, memory_limit, path,
                           "reading this policy")
            with np.load(path, allow_pickle=False) as data:
                fmt = str(data["format"]) if "format" in data.files else ""
                if fmt != FORMAT:
                    raise SolverError(f"{path}: not a ros_hrc policy file")
                version = int(data["version"])
                if version != VERSION:
                    raise SolverError(f"{path}: policy format version {version}, "
                                      f"this reader knows {VERSION}")
                alphas = data["alphas"]
                if not (np.issubdtype(alphas.dtype, np.number)
                        and np.all(np.isfinite(alphas))):
                    raise SolverError(f"{path}: the policy's vectors are not all finite numbers")
                return cls(alphas=alphas, actions=data["actions"],
                           state_names=[str(x) for x in data["state_names"]],
                           action_names=[str(x) for x in data["action_names"]],
                           discount=float(data["discount"]), lower=float(data["lower"]),
                           upper=float(data["upper"]), kind=str(data["kind"]),
                           model_name=str(data["model_name"]),
                           stats=json.loads(str(data["stats_json"])))
        except SolverError:
            raise
        except (OSError, ValueError, KeyError, EOFError, zipfile.BadZipFile) as exc:
            raise SolverError(f"{path}: cannot read policy ({exc})") from None


def save(policy: Policy, path: str) -> None:
    """Write ``policy`` to ``path``."""
    policy.save(path)


def load(path: str, model: Optional[Model] = None, memory_limit: Optional[int] = None,
         memory_in_use: int = 0) -> Policy:
    """Read a policy; with ``model``, also check it fits that model."""
    policy = Policy.load(path, memory_limit, memory_in_use)
    if model is not None:
        policy.check(model)
    return policy
