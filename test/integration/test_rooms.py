"""The ROS-free rooms import without rospy, none of them imports it, and imports point down."""
import ast
import json
import subprocess
import sys
from pathlib import Path

PACKAGE = Path(__file__).resolve().parents[2] / "src" / "ros_hrc"


#: Run in one fresh interpreter: each statement in a child forked from it before anything of
#: ours (or rospy, PyBullet) is imported, which prints the modules the statement left loaded.
#: A fork per statement is a fresh import of it without an interpreter's start, and without
#: importing again each time the third-party libraries the interpreter imported first
#: (``preload``; they import nothing of ROS).
_EACH_IN_A_FORK = """
import json, os, sys
exec(sys.argv[2])
for statement in json.loads(sys.argv[1]):
    reader, writer = os.pipe()
    child = os.fork()
    if child == 0:
        os.close(reader)
        exec(statement)
        with os.fdopen(writer, "w") as out:
            json.dump(sorted(sys.modules), out)
        os._exit(0)
    os.close(writer)
    with os.fdopen(reader) as answer:
        print(answer.read())
    _, status = os.waitpid(child, 0)
    if status:
        sys.exit(f"{statement!r} failed in its child (wait status {status})")
"""


#: What the rooms' checks import before they fork: numpy and SciPy, which most rooms use.
NUMERIC = "import numpy, scipy.sparse, scipy.special, scipy.stats"


def _imported_modules_after_each(*statements: str, preload: str = NUMERIC) -> list:
    """The modules loaded after each of ``statements``, each run alone in a process that
    had imported only ``preload``."""
    out = subprocess.run([sys.executable, "-c", _EACH_IN_A_FORK, json.dumps(statements),
                          preload],
                         capture_output=True, text=True)
    assert out.returncode == 0, out.stderr[-3000:]
    return [set(json.loads(line)) for line in out.stdout.splitlines()]


def _imported_modules_after(statement: str) -> set:
    return _imported_modules_after_each(statement)[0]


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
    together, *alone = _imported_modules_after_each(
        "; ".join(f"import {room}" for room in rooms), *(f"import {room}" for room in rooms))
    for room in rooms:
        assert room in together
    assert not {"rospy", "rosgraph", "roslib"} & together, "a ROS-free room pulls in ROS"
    for room, modules in zip(rooms, alone):   # one by one too: no room leans on another
        assert room in modules                 # having been imported
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
    rooms = ("ros_hrc.pomdp", "ros_hrc.link", "ros_hrc.commands.check", "ros_hrc.experiment.cli")
    for room, modules in zip(rooms, _imported_modules_after_each(*(f"import {room}"
                                                                  for room in rooms))):
        assert "pybullet" not in modules, room


def test_the_step_s_nodes_start_without_scipy():
    # The coordinator's node and the world's show a belief over types but hold no model:
    # SciPy would cost each about 0.3 s of CPU at every stack's start (docs/performance.md).
    nodes = ("ros_hrc.nodes.human_node", "ros_hrc.nodes.world_node")
    for node, modules in zip(nodes, _imported_modules_after_each(
            *(f"import {node}" for node in nodes), preload="")):
        assert node in modules
        assert "scipy" not in modules, f"{node} imports SciPy"
