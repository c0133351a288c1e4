"""The test folders hold what their names say (README, "Tests"): a test under test/unit imports
no ROS (rospy, the nodes, the generated messages) and no way to start a process (subprocess,
multiprocessing, Ray); those are test/nodes' and test/integration's."""
import ast
from pathlib import Path

UNIT = Path(__file__).resolve().parent
NOT_IN_UNIT = ("rospy", "rostest", "roslaunch", "rosgraph", "ros_hrc.nodes", "ros_hrc.msg",
               "ros_hrc.srv", "subprocess", "multiprocessing", "ray")


def imported(path: Path) -> set:
    """The modules ``path`` imports, anywhere in it (a lazy import inside a test counts)."""
    names = set()
    for node in ast.walk(ast.parse(path.read_text(encoding="utf-8"), str(path))):
        if isinstance(node, ast.Import):
            names.update(alias.name for alias in node.names)
        elif isinstance(node, ast.ImportFrom) and node.module and node.level == 0:
            names.add(node.module)
            names.update(f"{node.module}.{alias.name}" for alias in node.names)
    return names


def test_no_unit_test_imports_ros_or_starts_a_process():
    found = {f"{path.relative_to(UNIT)}: {name}" for path in sorted(UNIT.rglob("*.py"))
             for name in imported(path)
             if any(name == banned or name.startswith(banned + ".") for banned in NOT_IN_UNIT)}
    assert not found, sorted(found)
