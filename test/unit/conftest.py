"""Fixtures shared by the unit tests."""
import pytest

from ros_hrc.link.token import mint_token, read_token


@pytest.fixture
def link_token(tmp_path):
    """(token, its file): a launch's link token, made as hrc_check makes it, in a ROS_HOME of
    the test's own."""
    path = mint_token("unit_test", environ={"ROS_HOME": str(tmp_path / "ros_home")})
    return read_token(path), path
