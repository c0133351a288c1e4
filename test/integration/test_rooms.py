"""The ROS-free rooms import without rospy, none of them imports it, and imports point down."""
import ast
import subprocess
import sys
from pathlib import Path

PACKAGE = Path(__file__).resolve().parents[2] / "src" / "ros_hrc"


def _imported_modules_after(statement: str) -> set:
    code = f"import sys; {statement}; print('\\n'.join(sorted(sys.modules)))"
    out = subprocess.run([sys.executable, "-c", code], check=True, capture_output=True, text=True)
    return set(out.stdout.split())


def test_pomdp_world_and_link_import_without_ros():
    # The loop (task tables, settings, model checks, the launch's pre-flight), the experiments'
    # scoring, results store, statistics, plots and stack driver too: rospy comes in only
    # inside a worker (ros_hrc.nodes.experiment_cell), once it knows its own master.
    rooms = ("ros_hrc.pomdp", "ros_hrc.world", "ros_hrc.link", "ros_hrc.errors",
             "ros_hrc.agents.robots", "ros_hrc.tasks", "ros_hrc.tasks.seed",
             "ros_hrc.tasks.fabric", "ros_hrc.tasks.seed", "ros_hrc.settings",
             "ros_hrc.models", "ros_hrc.commands.check", "ros_hrc.experiment.store",
             "ros_hrc.experiment.statistics", "ros_hrc.experiment.plots",
             "ros_hrc.experiment.episode", "ros_hrc.experiment.stack",
             "ros_hrc.experiment.cli")
    modules = _imported_modules_after("; ".join(f"import {room}" for room in rooms))
    for room in rooms:
        assert room in modules
    assert not {"rospy", "rosgraph", "roslib"} & modules, "a ROS-free room pulls in ROS"
    for room in rooms:   # one by one too: no room leans on another having been imported
        modules = _imported_modules_after(f"import {room}")
        assert not {"rospy", "rosgraph", "roslib"} & modules, f"{room} pulls in ROS"


def test_the_loop_uses_no_sockets_library_of_ours_and_no_world():
    modules = _imported_modules_after("import ros_hrc.settings, ros_hrc.models")
    assert not {"ros_hrc.link", "ros_hrc.world", "pybullet", "websockets"} & modules


def test_the_old_results_module_is_gone():
    assert not (PACKAGE / "experiment" / "results.py").exists()


def test_experiment_never_imports_the_nodes():
    # Imports point down: nodes/experiment_cell.py imports experiment/, never the reverse.
    for path in sorted((PACKAGE / "experiment").glob("*.py")):
        for node in ast.walk(ast.parse(path.read_text())):
            if isinstance(node, ast.ImportFrom):
                names = [node.module or ""]
            elif isinstance(node, ast.Import):
                names = [a.name for a in node.names]
            else:
                continue
            assert not any(n.startswith("ros_hrc.nodes") for n in names), \
                f"{path.name}:{node.lineno} imports ros_hrc.nodes"
    modules = _imported_modules_after("import ros_hrc.experiment.cli")
    assert not any(m.startswith("ros_hrc.nodes") for m in modules)


def test_only_the_world_imports_pybullet():
    for room in ("ros_hrc.pomdp", "ros_hrc.link", "ros_hrc.commands.check", "ros_hrc.experiment.cli"):
        assert "pybullet" not in _imported_modules_after(f"import {room}")
