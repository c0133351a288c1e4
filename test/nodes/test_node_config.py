"""Every node reads its parameters one way (ros_hrc.nodes.common.read_config) into a typed
config, a launch setting's default and checks coming from the settings table alone."""
from dataclasses import dataclass, fields
from typing import Tuple

import pytest

from ros_hrc import settings
from ros_hrc.errors import HrcError
from ros_hrc.nodes.common import parameter, read_config
from ros_hrc.nodes.human_node import HumanNodeConfig
from ros_hrc.nodes.viz_node import VizNodeConfig
from ros_hrc.nodes.world_node import WorldNodeConfig
from ros_hrc.settings import SettingError


def params(**given):
    """A fake rospy.get_param over ``given`` (private names without their ``~``)."""
    def get_param(name, default):
        return given.get(name.lstrip("~"), default)
    return get_param


@dataclass(frozen=True)
class SomeConfig:
    seed: int = 0
    pomdp_port: int = 7070
    timeout: float = 30.0
    verbose: bool = False
    names: Tuple[str, ...] = ("a", "b")
    origin: Tuple[float, ...] = (0.0, 0.0)
    label: str = "x"
    sim: bool = parameter(False, "/use_sim_time")


def test_a_setting_takes_the_table_s_default_and_checks():
    config = read_config(SomeConfig, params())
    assert config == SomeConfig()
    assert read_config(SomeConfig, params(seed="", pomdp_port=" 7071 ")).pomdp_port == 7071
    with pytest.raises(SettingError) as info:
        read_config(SomeConfig, params(pomdp_port=70000))
    assert str(info.value) == "pomdp_port:=70000: must be an integer from 1 to 65535"


def test_other_fields_are_coerced_to_their_default_s_type():
    config = read_config(SomeConfig, params(timeout="2", verbose="Yes", names="c, d e",
                                            origin=[1, "2.5"], label="y", sim=True))
    assert (config.timeout, config.verbose, config.names, config.origin, config.label) == \
        (2.0, True, ("c", "d", "e"), (1.0, 2.5), "y")
    assert config.sim is False                 # read from /use_sim_time, not ~sim
    assert read_config(SomeConfig, params(**{"/use_sim_time": True})).sim is True
    assert read_config(SomeConfig, params(names=["p"])).names == ("p",)


@pytest.mark.parametrize("config_type", [HumanNodeConfig, WorldNodeConfig])
def test_a_node_s_settings_default_to_the_table(config_type):
    """What a node is given when a parameter is unset is the table's default, whatever its
    dataclass says; the dataclasses say the same."""
    config = read_config(config_type, params())
    for f in fields(config_type):
        if f.name in settings.SETTINGS:
            assert getattr(config, f.name) == settings.default(f.name), f.name
            assert f.default == settings.default(f.name), f.name


def test_the_world_node_decides_what_its_parameters_leave_open(monkeypatch, tmp_path):
    monkeypatch.setenv("ROS_HOME", str(tmp_path))
    config = WorldNodeConfig.from_params(params())
    assert (config.away_time, config.pause_when_idle, config.real_time_factor) == \
        (0.0, False, 1.0)
    assert config.snapshot_dir == str(tmp_path / "hrc_snapshots")
    assert config.model_dir.endswith("models/urdf")
    assert config.loop_nodes == ("hrc_human",)
    config = WorldNodeConfig.from_params(params(real_time_factor="0", away_time="0.8",
                                                loop_nodes="a,b", tf_rate=10,
                                                **{"/use_sim_time": True}))
    assert (config.pause_when_idle, config.away_time, config.loop_nodes, config.tf_rate,
            config.use_sim_time) == (True, 0.8, ("a", "b"), 10.0, True)
    assert WorldNodeConfig.from_params(params(real_time_factor="0", pause_when_idle="false")
                                       ).pause_when_idle is False
    with pytest.raises(SettingError, match=r"^belt_speed:=-5: must be a number from 0 to 0.5"):
        WorldNodeConfig.from_params(params(belt_speed="-5"))
    with pytest.raises(ValueError, match="~tf_rate must be > 0"):
        WorldNodeConfig.from_params(params(tf_rate=0))


def test_under_hrc_launch_the_world_takes_its_settings_from_the_checked_configuration():
    """hrc.launch's pre-flight checked and resolved the world's settings with the rest (its
    hrc/config): the world reads them there, and world.launch runs no pre-flight of its own."""
    from ros_hrc.commands.check import check
    # (pause_when_idle: auto, decided there by the mode, which the world is not given)
    resolved = check(["belt_speed:=0.05", "real_time_factor:=2", "mode:=manual"],
                     port_check=False)
    config = WorldNodeConfig.from_params(params(
        checked_config="hrc/config", belt_speed="0.3", tf_rate=10,
        **{"hrc/config": resolved, "/use_sim_time": True}))
    assert (config.belt_speed, config.real_time_factor, config.pause_when_idle,
            config.snapshot_dir, config.tf_rate, config.use_sim_time) == (
        0.05, 2.0, True, resolved["snapshot_dir"], 10.0, True)
    with pytest.raises(HrcError, match="~checked_config: no resolved configuration at "
                                       "hrc/config"):
        WorldNodeConfig.from_params(params(checked_config="hrc/config"))


def test_the_viz_node_s_scenery_is_the_world_s():
    assert read_config(VizNodeConfig, params()) == VizNodeConfig(
        frame="world", bars_origin=(-1.3, -1.35, 1.75), bar_spacing=0.13, bar_height=0.3,
        text_position=(-0.55, 0.1, 2.48), caption_columns=100, holder_height=2.15,
        belt_size=(2.0, 0.4, 0.04), object_size=0.06)
    config = read_config(VizNodeConfig, params(frame="map", bars_origin=[0, 1, 2]))
    assert (config.frame, config.bars_origin) == ("map", (0.0, 1.0, 2.0))
