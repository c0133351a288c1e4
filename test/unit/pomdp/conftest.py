"""Fixtures of the solver tests: Tiger and a chain MDP, built in code (solver_models.py)."""
import pytest

from ros_hrc.pomdp.model import Model
from solver_models import build_chain, build_tiger


@pytest.fixture
def tiger() -> Model:
    return build_tiger()


@pytest.fixture
def chain() -> Model:
    return build_chain()
