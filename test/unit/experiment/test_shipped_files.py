"""The files a cell takes to a cluster's node (ros_hrc.experiment.shipped_files): a node that
has the package but none of the driver's paths gets every file a sequence cell names, and
its copies load as the stack loads them. No Ray here: test_cluster.py runs real nodes."""
import shutil
from pathlib import Path

from ros_hrc import tasks
from ros_hrc.agents.library import library_manifest
from ros_hrc.experiment.shipped_files import cell_files, place_cell_files
from ros_hrc.experiment.stack import CellSpec
from ros_hrc.model_files import model_names
from ros_hrc.processes.selection import load_selection
from ros_hrc.tasks.schedule import parse_schedule

FABRIC = tasks.get("fabric")
FABRIC_MODELS = library_manifest("fabric").parent


def _driver_files(tmp_path: Path) -> Path:
    """A copy of fabric's library, selector model and a schedule file in a folder of the
    driver's own, as a user's --library, --selector-model and --schedule name them."""
    driver = tmp_path / "driver"
    shutil.copytree(FABRIC_MODELS, driver / "fabric")
    (driver / "two_humans.toml").write_text(
        '[[block]]\nhuman = "expert_tired_noncollaborative"\ntasks = 2\n'
        '[[block]]\nhuman = "beginner_tired_collaborative"\ntasks = 3\n')
    return driver


def _sequence_cell(driver: Path, schedule: str) -> CellSpec:
    return CellSpec(human_model="fabric", robot_policy="bpr", seed=2, episodes=[0],
                    robot_model=str(driver / "fabric" / "robot" / "base.pomdpx"),
                    human_model_file=str(driver / "fabric" / "human" /
                                         "expert_tired_noncollaborative.pomdpx"),
                    sequence=5,
                    extra_args=["task:=fabric", "tasks:=5", "selector:=bpr",
                                f"library:={driver / 'fabric' / 'library.toml'}",
                                f"selector_model:={driver / 'fabric' / 'selector_model.json'}",
                                f"schedule:={schedule}"])


def _arguments(spec: CellSpec) -> dict:
    return dict(word.split(":=", 1) for word in spec.extra_args)


def test_a_sequence_cell_s_files_reach_a_node_without_the_driver_s_paths(tmp_path):
    driver = _driver_files(tmp_path)
    cell = _sequence_cell(driver, str(driver / "two_humans.toml"))
    files = cell_files(cell, {})
    # The node: the driver's folder is gone there.
    shutil.rmtree(driver)
    node = place_cell_files(cell, files, tmp_path / "node" / "models")

    given = _arguments(node)
    for name in ("library", "selector_model", "schedule"):
        assert Path(given[name]).is_file(), name
        assert Path(given[name]).is_relative_to(tmp_path / "node"), (name, given[name])
    for name in ("task", "tasks", "selector"):
        assert given[name] == _arguments(cell)[name]
    assert Path(node.robot_model).is_file() and Path(node.human_model_file).is_file()

    # The copies load together as the robot process loads them: every policy's model is
    # the node's copy, and the selector model fits the library.
    selection = load_selection("bpr", given["library"], given["selector_model"], FABRIC)
    assert len(selection.library.policies) == len(
        load_selection("bpr", "auto", "auto", FABRIC).library.policies)
    for policy in selection.library.policies:
        if policy.robot_model is not None:
            assert policy.robot_model.is_relative_to(tmp_path / "node"), policy.name
    schedule = parse_schedule(given["schedule"], model_names(FABRIC.model_dirs["human"]),
                              "expert_tired_noncollaborative", "fabric")
    assert [b.human for b in schedule.blocks] == ["expert_tired_noncollaborative",
                                                  "beginner_tired_collaborative"]


def test_words_that_name_no_file_go_as_they_are(tmp_path):
    driver = _driver_files(tmp_path)
    cell = _sequence_cell(driver, "fabric")
    cell.extra_args[3:5] = ["library:=auto", "selector_model:=auto"]
    # A file called "fabric" where the driver runs is not FABRIC's schedule.
    (tmp_path / "fabric").write_text("not a schedule\n")
    files = cell_files(cell, {})
    node = place_cell_files(cell, files, tmp_path / "node" / "models")
    assert _arguments(node)["library"] == "auto"
    assert _arguments(node)["selector_model"] == "auto"
    assert _arguments(node)["schedule"] == "fabric"


def test_a_library_whose_models_lie_beside_its_folder_keeps_its_layout(tmp_path):
    driver = _driver_files(tmp_path)
    # The manifest in a folder of its own, naming the models as ../fabric/robot/...
    (driver / "mine").mkdir()
    text = (driver / "fabric" / "library.toml").read_text()
    (driver / "mine" / "library.toml").write_text(
        text.replace('model = "robot/', 'model = "../fabric/robot/'))
    cell = _sequence_cell(driver, "fabric")
    cell.extra_args[3] = f"library:={driver / 'mine' / 'library.toml'}"
    files = cell_files(cell, {})
    shutil.rmtree(driver)
    node = place_cell_files(cell, files, tmp_path / "node" / "models")
    library = load_selection("random", _arguments(node)["library"], "auto", FABRIC).library
    assert library.manifest.is_relative_to(tmp_path / "node")
    assert all(p.robot_model.is_relative_to(tmp_path / "node")
               for p in library.policies if p.robot_model is not None)


def test_a_file_named_by_many_cells_is_read_once(tmp_path):
    driver = _driver_files(tmp_path)
    cache = {}
    first = cell_files(_sequence_cell(driver, "fabric"), cache)
    (driver / "fabric" / "selector_model.json").write_text("{}")   # read before: not again
    second = cell_files(_sequence_cell(driver, "fabric"), cache)
    assert first == second
