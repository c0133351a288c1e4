"""Fixtures for the world's unit tests: small, headless worlds, closed after each test."""
from typing import Iterator

import pytest

from ros_hrc.world import World, WorldConfig


@pytest.fixture
def world() -> Iterator[World]:
    """The default scene, headless, belt at its default speed."""
    with World(WorldConfig(seed=3)) as w:
        yield w


@pytest.fixture
def still_world() -> Iterator[World]:
    """The default scene with the belt stopped, so the object stays where it is put."""
    with World(WorldConfig(seed=3, belt_speed=0.0)) as w:
        yield w
