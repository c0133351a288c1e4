"""Writing POMDPX (:mod:`ros_hrc.pomdp.pomdpx`): :func:`dump` / :func:`save`.

:func:`dump` writes a flat model: one state variable (``state_0``/``state_1``), one action
variable, one observation variable (none for an MDP, whose state variable is ``fullyObs``),
one reward function over (action, state_0, state_1). Names come from the model's own POMDPX
variables when it was read from a one-variable file. A ``values: cost`` model is marked
``[values: cost]`` in the ``<Description>`` (rewards are still written as rewards = -cost) so
the flag survives a round trip. A model with mixed observability is written as a POMDP whose
observation still carries the fully observed values after each step, but its ``observed_key``
is not kept: read back, the start is no longer conditioned on them. Numbers are written as
the shortest text that reads back exactly, so :func:`ros_hrc.pomdp.pomdpx_reader.loads` gives
identical tables.
"""
from __future__ import annotations

from pathlib import Path
from typing import Dict, List, Sequence
from xml.sax.saxutils import escape, quoteattr

import numpy as np
import scipy.sparse as sp

from ros_hrc.pomdp.fileformat import (POMDPX_NAME, POMDPX_NAME_RULE, check_writable_model_names,
                                      format_number, is_identity, stored_entries,
                                      written_as_matrix)
from ros_hrc.pomdp.model import Model
from ros_hrc.pomdp.output import write_text_atomically
from ros_hrc.pomdp.pomdpx_xml import COST_MARK

__all__ = ["dump", "save"]

_DEFAULT_NAMES = {"state_prev": "state_0", "state_curr": "state_1", "action": "action_agent",
                  "observation": "obs_agent", "reward": "reward_agent"}


def save(model: Model, path) -> None:
    """Write ``model`` to ``path`` as POMDPX (the whole file or nothing)."""
    write_text_atomically(path, dump(model))


def _names(model: Model) -> Dict[str, str]:
    """Variable names: the model's own when it came from a one-variable POMDPX file."""
    names = dict(_DEFAULT_NAMES)
    info = model.meta.get("pomdpx") if isinstance(model.meta, dict) else None
    if info and len(info.get("state_variables", [])) == 1:
        names["state_prev"] = info["state_variables"][0]["prev"]
        names["state_curr"] = info["state_variables"][0]["curr"]
        names["action"] = info.get("action_variable", names["action"])
        if len(info.get("observation_variables", [])) == 1:
            names["observation"] = info["observation_variables"][0]["name"]
        if len(info.get("reward_variables", [])) == 1:
            names["reward"] = info["reward_variables"][0]
    return names


def _matrix_text(dense: np.ndarray, indent: str) -> str:
    rows = [indent + " ".join(format_number(x) for x in row) for row in dense]
    return "\n" + "\n".join(rows) + "\n" + indent[:-2]


def _entries(tag: str, model_actions: Sequence[str], tables: Sequence[sp.csr_matrix],
             rows: Sequence[str], cols: Sequence[str]) -> List[str]:
    """Each action's table as <Entry> elements: a matrix when small, else one entry per
    non-zero."""
    out = []
    ind = "        "
    for a, name in enumerate(model_actions):
        if written_as_matrix(tables[a]):
            dense = sp.csr_matrix(tables[a]).toarray()
            out.append(f"{ind}<Entry>\n{ind}  <Instance>{escape(name)} - -</Instance>\n"
                       f"{ind}  <{tag}>{_matrix_text(dense, ind + '    ')}</{tag}>\n"
                       f"{ind}</Entry>")
            continue
        for r, c, value in stored_entries(tables[a]):
            if value != 0:
                out.append(f"{ind}<Entry><Instance>{escape(name)} {escape(rows[r])} "
                           f"{escape(cols[c])}</Instance>"
                           f"<{tag}>{format_number(value)}</{tag}></Entry>")
    return out


def dump(model: Model) -> str:
    """The model as one-variable POMDPX text; ``loads`` reads it back to identical tables."""
    check_writable_model_names(model, POMDPX_NAME, POMDPX_NAME_RULE)
    names = _names(model)
    mdp = model.fully_observable and list(model.observations) == list(model.states) and \
        all(is_identity(o) for o in model.O)
    description = f"{model.name or 'model'}: written by ros_hrc"
    if model.source:
        description += f" from {Path(model.source).name}"
    if model.minimise:
        description += f" {COST_MARK}"
    lines = ['<?xml version="1.0" encoding="UTF-8"?>',
             f'<pomdpx version="1.0" id={quoteattr(model.name or "model")}',
             '        xmlns:xsi="http://www.w3.org/2001/XMLSchema-instance"',
             '        xsi:noNamespaceSchemaLocation="pomdpx.xsd">',
             f"  <Description>{escape(description)}</Description>",
             f"  <Discount>{format_number(model.discount)}</Discount>",
             "  <Variable>",
             f'    <StateVar vnamePrev={quoteattr(names["state_prev"])} '
             f'vnameCurr={quoteattr(names["state_curr"])} fullyObs="{"true" if mdp else "false"}">',
             f"      <ValueEnum>{escape(' '.join(model.states))}</ValueEnum>",
             "    </StateVar>"]
    if not mdp:
        lines += [f'    <ObsVar vname={quoteattr(names["observation"])}>',
                  f"      <ValueEnum>{escape(' '.join(model.observations))}</ValueEnum>",
                  "    </ObsVar>"]
    lines += [f'    <ActionVar vname={quoteattr(names["action"])}>',
              f"      <ValueEnum>{escape(' '.join(model.actions))}</ValueEnum>",
              "    </ActionVar>",
              f'    <RewardVar vname={quoteattr(names["reward"])}/>',
              "  </Variable>",
              "  <InitialStateBelief>",
              f"    <CondProb><Var>{escape(names['state_prev'])}</Var><Parent>null</Parent>",
              '      <Parameter type="TBL"><Entry><Instance>-</Instance>',
              "        <ProbTable>" + " ".join(format_number(x) for x in model.initial_belief)
              + "</ProbTable>",
              "      </Entry></Parameter>",
              "    </CondProb>",
              "  </InitialStateBelief>",
              "  <StateTransitionFunction>",
              f"    <CondProb><Var>{escape(names['state_curr'])}</Var>"
              f"<Parent>{escape(names['action'])} {escape(names['state_prev'])}</Parent>",
              '      <Parameter type="TBL">']
    lines += _entries("ProbTable", model.actions, model.T, model.states, model.states)
    lines += ["      </Parameter>", "    </CondProb>", "  </StateTransitionFunction>"]
    if not mdp:
        lines += ["  <ObsFunction>",
                  f"    <CondProb><Var>{escape(names['observation'])}</Var>"
                  f"<Parent>{escape(names['action'])} {escape(names['state_curr'])}</Parent>",
                  '      <Parameter type="TBL">']
        lines += _entries("ProbTable", model.actions, model.O, model.states,
                          model.observations)
        lines += ["      </Parameter>", "    </CondProb>", "  </ObsFunction>"]
    lines += ["  <RewardFunction>",
              f"    <Func><Var>{escape(names['reward'])}</Var><Parent>{escape(names['action'])} "
              f"{escape(names['state_prev'])} {escape(names['state_curr'])}</Parent>",
              '      <Parameter type="TBL">']
    lines += _entries("ValueTable", model.actions, model.R, model.states, model.states)
    lines += ["      </Parameter>", "    </Func>", "  </RewardFunction>", "</pomdpx>"]
    return "\n".join(lines) + "\n"
